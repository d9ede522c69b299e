"""What a new user reads when something is wrong (issue 38, item 9): a missing file in
one line, a text file named ``.stl`` refused by name, no Rust source paths."""

from __future__ import annotations

import json
import re

import pytest

from arduinobot.cli.main import main
from tests.helpers.cli import run_cli
from tests.helpers.serve import free_port


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Run the command line; its exit code and stderr (argparse's own refusals exit)."""
    try:
        rc = main(argv)
    except SystemExit as e:
        rc = int(e.code or 0)
    return rc, capsys.readouterr().err


# -- a missing or unreadable file: one line naming it, not 15 lines of usage -----------------

@pytest.mark.parametrize("argv", [
    ["task", "{missing}"],
    ["task", "{bad_yaml}"],
    ["scene", "load", "{missing}"],
    ["plan", "--request", "{missing}"],
    ["plan", "--request", "{bad_json}"],
    ["execute", "--request", "{missing}", "--sim"],
    ["view", "--scene", "{missing}", "--png", "{out}"],
    ["scene", "add-mesh", "bin", "{missing_stl}", "--pose", "0.3,0,0.1"],
    ["scene", "see", "{missing_png}"],
])
def test_a_file_that_cannot_be_read_is_one_line_naming_it(argv, tmp_path, capsys):
    files = {"missing": tmp_path / "nosuch.json", "missing_stl": tmp_path / "nosuch.stl",
             "missing_png": tmp_path / "nosuch.png", "out": tmp_path / "out.png",
             "bad_yaml": tmp_path / "task.yaml", "bad_json": tmp_path / "req.json"}
    files["bad_yaml"].write_text("steps: [\n")
    files["bad_json"].write_text("{bad")
    typed = [a.format(**files) for a in argv]
    rc, err = _refused(typed, capsys)
    named = next(str(files[k]) for k in files if "{" + k + "}" in argv)
    assert rc == 2, err
    assert "usage:" not in err, err
    assert err.startswith(f"arduinobot {argv[0]}")
    assert named in err.splitlines()[0]
    if "{missing" in " ".join(argv):
        assert err.count("\n") == 1 and "No such file" in err


# -- a text file named .stl -----------------------------------------------------------------

@pytest.mark.parametrize("text", [
    "this is not a mesh\n",  # shorter than a binary STL's header
    "hello, this is a readme saved as .stl by mistake; long enough to hold a binary "
    "STL's 80-byte header and a triangle count\n",  # whose 'count' would be 1.7e9
])
def test_a_text_file_named_stl_is_refused_naming_it(text, tmp_path, capsys):
    f = tmp_path / "bin.stl"
    f.write_text(text)
    # refused before any service is asked (none listens on this port)
    rc, err = _refused(["scene", "add-mesh", "bin", str(f), "--pose", "0.3,0,0.1",
                        "--connect", f"tcp/127.0.0.1:{free_port()}"], capsys)
    assert rc == 2
    assert err.startswith(f"arduinobot scene add-mesh: error: {f}: not an STL mesh: neither "
                          "text beginning with 'solid' nor a binary STL")
    assert "triangles," not in err and "more than" not in err


# -- Zenoh's messages without the Rust source paths of its build ----------------------------

@pytest.mark.parametrize("connect", ["tcp/127.0.0.1:{port}", "foo"])
def test_a_service_that_cannot_be_reached_is_said_without_rust_paths(connect, capsys):
    rc, err = _refused(["fk", "--joints", "0,0,0", "--connect",
                        connect.format(port=free_port())], capsys)
    assert rc == 3
    assert err.startswith("arduinobot: service unavailable (connect_failed): cannot reach ")
    assert ".rs:" not in err and ".cargo" not in err, err
    if connect == "foo":  # what Zenoh says is wrong is kept
        assert "Endpoints must be of the form <protocol>/<address>" in err


# -- a mistyped key: the closest known one, in the refusal naming the field -----------------

_START = {"joint_1": 0, "joint_2": 0, "joint_3": 0, "joint_4": 0}


@pytest.mark.parametrize("task, field, said", [
    ({"start": _START, "stpes": [{"gripper": "open"}]},
     "task", "unknown field 'stpes' (did you mean 'steps'?) of a task"),
    ({"start": _START, "steps": [{"gripper": "open", "lable": "x"}]},
     "steps[0]", "unknown field 'lable' (did you mean 'label'?) of a gripper step"),
    ({"start": _START, "steps": [{"move": {"jionts": {"joint_1": 0.3}}}]},
     "steps[0].move", "unknown 'jionts' (did you mean 'joints'?)"),
    ({"start": _START, "steps": [{"mvoe": {"named": "home"}}]},
     "steps[0]", "unknown 'mvoe' (did you mean 'move'?)"),
    ({"start": _START, "obstacles": [{"id": "t", "shape": "box", "szie": [1, 1, 0.1],
                                      "xyz": [0, 1, 0.5]}], "steps": [{"gripper": "open"}]},
     "obstacles[0]", "unknown field 'szie' (did you mean 'size'?) of an obstacle"),
])
def test_a_mistyped_key_in_a_task_file_names_the_closest(task, field, said, tmp_path, capsys):
    f = tmp_path / "task.json"
    f.write_text(json.dumps(task))
    rc, err = _refused(["task", str(f)], capsys)
    assert rc == 1
    assert err.startswith(f"arduinobot: INVALID_REQUEST: {field}: "), err
    assert said in err.splitlines()[0]


@pytest.mark.parametrize("request_, said", [
    ({"goal": {"named": "home"}, "stat": {"joint_1": 0.1}},
     "stat: unknown field 'stat' (did you mean 'start'?)"),
    ({"goal": {"jionts": {"joint_1": 0.1}}},
     "goal: must be exactly one of: {joints}, {named}, {position}, {line}; unknown 'jionts' "
     "(did you mean 'joints'?)"),
])
def test_a_mistyped_key_in_a_request_names_the_closest(request_, said, tmp_path, capsys):
    f = tmp_path / "req.json"
    f.write_text(json.dumps(request_))
    rc, err = _refused(["plan", "--request", str(f), "--local"], capsys)
    assert rc == 1
    assert err.startswith(f"arduinobot: INVALID_REQUEST: {said}"), err


# -- a partial --goal: all of the group's joints, or by name with a note --------------------

def test_a_partial_goal_is_refused_positionally_and_said_by_name(capsys):
    # one value for the arm's three joints: which one did the user mean? not joint_1
    # silently, with joint_2 and joint_3 left where they start
    rc, err = _refused(["plan", "--goal", "0.5", "--local"], capsys)
    assert rc == 2
    assert err.splitlines()[-1] == (
        "arduinobot plan: error: --goal gives 1 value(s) for the 3 joints of group 'arm' "
        "(joint_1, joint_2, joint_3): give all 3, or name=value for the joints to move (the "
        "others then keep their start value)")
    # by name, a partial goal is what the user asked for: planned, and the rest said
    assert main(["plan", "--goal", "joint_1=0.5", "--start", "0,0.2,0.1,0", "--local",
                 "--seed", "1", "--json", "-"]) == 0
    out = capsys.readouterr()
    assert ("note: --goal moves joint_1; joint_2, joint_3 of group 'arm' keep their start "
            "value") in out.err
    end = json.loads(out.out)["trajectory"]["points"][-1]["positions"]
    assert end[:3] == pytest.approx([0.5, 0.2, 0.1], abs=1e-6)


# -- the summary's table on an arm with longer joint names ----------------------------------

def test_the_plan_summary_keeps_its_columns_for_the_so101s_joint_names(tmp_path, capsys):
    from tests.helpers.so101 import make_so101
    urdf = make_so101(tmp_path)
    assert main(["plan", "--local", str(urdf), "--named", "ready", "--seed", "1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("joint "))
    rows = lines[head + 1:lines.index("limits applied (full figure from, x scaling):")]
    assert [r.split()[0] for r in rows][:3] == ["shoulder_pan", "shoulder_lift", "elbow_flex"]
    # each figure ends where its heading ends ('shoulder_lift' overran a 10-wide column)
    ends = [m.end() for m in re.finditer(r"\S+", lines[head])
            if m.group() in ("peak", "limit", "|effort|")]
    for r in rows:
        assert [m.end() for m in re.finditer(r"\S+", r)][1:] == ends, (lines[head], r)


# -- the model's warnings: once, not in every command and every worker ----------------------

_XACRO = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="xw">
  <xacro:property name="pi" value="3.14159"/>
  <xacro:macro name="part" params="name size">
    <link name="${name}">
      <inertial><mass value="1"/>
        <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
      <visual><geometry><box size="${size}"/></geometry></visual>
      <collision><geometry><box size="${size}"/></geometry></collision>
    </link>
  </xacro:macro>
  <xacro:part name="base" size="0.1 0.1 0.1"/>
  <xacro:part name="arm" size="0.05 0.05 0.3"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="${-pi/2}" upper="${pi/2}" effort="5" velocity="2"/></joint>
</robot>
"""


def test_xacros_own_warnings_are_the_models_said_once(tmp_path, capsys):
    """xacro printed 'redefining global symbol: pi' on stderr itself, in every command."""
    xacro_file = tmp_path / "r.urdf.xacro"
    xacro_file.write_text(_XACRO)
    assert main(["fk", "--local", str(xacro_file), "--joints", "0.1"]) == 0
    err = capsys.readouterr().err
    assert "redefining" not in err and "WARNING" not in err, err
    assert err.splitlines()[-1].startswith("arduinobot fk: the model has ")
    assert "(`arduinobot check FILE` lists them; -v shows them here)" in err
    # check lists it as one finding, and the log does not say it a second time
    assert main(["check", str(xacro_file)]) == 0
    cap = capsys.readouterr()
    said = f"xacro: redefining global symbol: pi (in {xacro_file})"
    assert f"WARN  xacro              r.urdf.xacro: {said}" in cap.out
    assert said not in cap.err
    # -v shows each once, at INFO (typed: the log goes where the command line puts it)
    r = run_cli("-v", "fk", "--local", str(xacro_file), "--joints", "0.1", timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count(said) == 1 and f"INFO arduinobot.description.loader: {said}" \
        in r.stderr, r.stderr


@pytest.mark.slow
def test_serve_logs_the_models_warnings_once_not_per_worker(course_ws, tmp_path):
    from tests.helpers.serve import start_server
    srv = start_server([str(course_ws.xacro), "--package-dir", str(course_ws.src),
                        "--workers", "2", "--no-robot",
                        "--cache-dir", str(tmp_path / "cache")], timeout=600)
    try:
        log = "\n".join(srv.stderr_lines)
    finally:
        srv.stop()
    assert log.count("<material> inside <geometry> is ignored") == 1, log
    for joint in ("joint_1", "joint_2", "joint_3", "joint_4"):
        assert log.count(f"{joint}: the acceleration derived from effort and inertia") == 1
