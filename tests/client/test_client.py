"""The Python client's error handling and the plan/fk/ik/check-state commands."""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import threading

import numpy as np
import pytest
import zenoh

from arduinobot.cli.argtypes import UsageError, joint_map, joint_values, obstacle
from arduinobot.cli.main import build_parser, main
from arduinobot.client import errors
from arduinobot.client.client import PlannerClient, encode_body
from arduinobot.client.replies import PlanReply
from arduinobot.contract.zconfig import zenoh_config
from tests.helpers.serve import REPO as ROOT
from tests.helpers.serve import free_port


def test_every_wire_code_has_its_class():
    for code, cls in errors.ERRORS.items():
        e = errors.error_from_reply({"error": {"code": code, "message": "m",
                                               "details": {"x": 1}}})
        assert type(e) is cls and e.code == code and e.details == {"x": 1}
    odd = errors.error_from_reply({"error": {"code": "NEW_CODE", "message": "m"}})
    assert type(odd) is errors.ServiceError and odd.code == "NEW_CODE"


def test_no_endpoint_is_connect_failed_with_a_hint():
    with pytest.raises(errors.ServiceUnavailable) as e:
        PlannerClient(f"tcp/127.0.0.1:{free_port()}")
    assert e.value.reason == "connect_failed" and "arduinobot serve" in e.value.message


@pytest.fixture
def fake_service():
    """A real zenoh peer whose queryables misbehave: one never replies, one sends a
    non-JSON reply_err (as Zenoh itself or a foreign service would)."""
    port = free_port()
    s = zenoh.open(zenoh_config(mode="peer", listen=[f"tcp/127.0.0.1:{port}"]))
    held, done = [], threading.Event()
    qs = [s.declare_queryable("fake/fk", held.append, complete=True),
          s.declare_queryable("fake/ik", lambda q: q.reply_err(b"access denied"),
                              complete=True)]
    yield f"tcp/127.0.0.1:{port}"
    done.set()
    for q in held:
        q.drop()
    for q in qs:
        q.undeclare()
    s.close()


def test_silent_queryable_is_timeout_and_foreign_error_is_zenoh_error(fake_service):
    with PlannerClient(fake_service, prefix="fake", timeout=0.5) as c:
        with pytest.raises(errors.ServiceUnavailable) as e:
            c.fk({})
        assert e.value.reason == "timeout"
        with pytest.raises(errors.ServiceUnavailable) as e:
            c.ik([0, 1, 1])
        assert e.value.reason == "zenoh_error" and "access denied" in e.value.message
        with pytest.raises(errors.ServiceUnavailable) as e:
            c.health()
        assert e.value.reason == "no_route"


def test_local_and_service_plans_agree(server, tmp_path, capsys):
    req = {"start": {"joint_1": 0.3}, "goal": {"named": "reach_right"}, "seed": 5,
           "sample_rate": 40}
    path = tmp_path / "req.json"
    path.write_text(json.dumps(req))
    assert main(["plan", "--request", str(path), "--local", "--json", "-"]) == 0
    local = json.loads(capsys.readouterr().out)
    assert main(["plan", "--request", str(path), "--connect", server.endpoint,
                 "--json", "-"]) == 0
    remote = json.loads(capsys.readouterr().out)
    assert local["trajectory"] == remote["trajectory"]
    assert local["path"] == remote["path"]


def test_plan_command_prints_a_summary_and_writes_files(server, tmp_path, capsys):
    csv_path, json_path = tmp_path / "t.csv", tmp_path / "t.json"
    rc = main(["plan", "--goal", "0.5,0.3,-0.4", "--start", "joint_2=0.1", "--seed", "1",
               "--connect", server.endpoint,
               "--csv", str(csv_path), "--json", str(json_path)])
    out = capsys.readouterr().out
    assert rc == 0
    assert "duration" in out and "joint_3" in out and "timing:" in out
    body = json.loads(json_path.read_text())
    res = PlanReply.parse(body)
    rows = csv_path.read_text().splitlines()
    assert rows[0].startswith("time_from_start,joint_1.position")
    assert len(rows) == len(res.times) + 1
    assert [float(v) for v in rows[-1].split(",")[:5]] == [res.times[-1], *res.positions[-1]]
    assert res.positions[-1][:3] == pytest.approx([0.5, 0.3, -0.4], abs=1e-6)
    assert res.positions[0][1] == pytest.approx(0.1)


def test_plan_command_errors(server, capsys):
    assert main(["plan", "--goal", "joint_5=0.2", "--connect", server.endpoint]) == 1
    err = capsys.readouterr().err
    assert "INVALID_REQUEST" in err and "joint_4" in err
    assert main(["plan", "--named", "home", "--connect",
                 f"tcp/127.0.0.1:{free_port()}"]) == 3
    assert "arduinobot serve" in capsys.readouterr().err


def test_fk_ik_check_state_commands(server, capsys):
    ep = ["--connect", server.endpoint]
    assert main(["fk", "--joints", "0,0,0", "--link", "claw_support", *ep]) == 0
    assert "claw_support" in capsys.readouterr().out
    assert main(["ik", "--position", "0,1.0,1.2", "--json", *ep]) == 0
    assert json.loads(capsys.readouterr().out)["solutions"]
    assert main(["check-state", "--joints", "0,0.3", *ep]) == 0
    assert "VALID" in capsys.readouterr().out
    assert main(["check-state", "--joints", "0,0.3", "--obstacle",
                 "box:b:1,1,1@0,0.5,1.5", *ep]) == 1
    assert "b" in capsys.readouterr().out


def test_check_state_help_tells_it_apart_from_the_model_checker(capsys):
    with pytest.raises(SystemExit):
        main(["check-state", "--help"])
    text = capsys.readouterr().out
    assert "arduinobot check" in text and "MODEL" in text


def test_every_command_a_help_text_names_exists():
    # the help of plan --goal and of check-state once sent users to `arduinobot model`,
    # which is not a command
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    texts = [parser.format_help(), *(p.format_help() for p in sub.choices.values())]
    # a command quoted as one (`arduinobot info`, 'arduinobot COMMAND --help'), not prose
    named = {m for t in texts for m in re.findall(r"[`']arduinobot ([a-z][a-z-]+)", t)}
    assert named and named <= set(sub.choices), named - set(sub.choices)


def test_obstacle_and_joint_options_parse():
    assert obstacle("box:table:1,1,0.1@0,1,0.5@0,0,0.3") == {
        "id": "table", "shape": "box", "size": [1, 1, 0.1], "xyz": [0, 1, 0.5],
        "rpy": [0, 0, 0.3]}
    assert obstacle("sphere:s:0.2@1,2,3") == {"id": "s", "shape": "sphere", "radius": 0.2,
                                               "xyz": [1, 2, 3]}
    assert obstacle("cylinder:c:0.1,2")["length"] == 2
    with pytest.raises(argparse.ArgumentTypeError, match="box:ID"):
        obstacle("cone:c:1")
    with pytest.raises(argparse.ArgumentTypeError, match="size '1,1' needs 3 numbers"):
        obstacle("box:b:1,1")
    names = ("joint_1", "joint_2", "joint_3")
    assert joint_map(joint_values("0.5,0.3"), names, "--goal") == {"joint_1": 0.5,
                                                                   "joint_2": 0.3}
    assert joint_map(joint_values("joint_3=-0.4"), names, "--goal") == {"joint_3": -0.4}
    with pytest.raises(UsageError, match="--goal: 4 values for 3 joints"):
        joint_map(joint_values("1,2,3,4"), names, "--goal")
    with pytest.raises(argparse.ArgumentTypeError, match="joint_1: 'x'"):
        joint_values("joint_1=x")


def _usage_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run the CLI expecting argparse's usage error: exit 2, 'arduinobot <cmd>: error:'."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: arduinobot " + argv[0])
    return err.splitlines()[-1]


def test_bad_values_are_usage_errors_naming_the_flag(capsys, tmp_path):
    assert _usage_error(["plan", "--goal", "0.5,x"], capsys) == \
        "arduinobot plan: error: argument --goal: '0.5,x' must be comma-separated numbers"
    assert "argument --position: '0,1' needs 3 numbers" in _usage_error(
        ["ik", "--position", "0,1", "--local"], capsys)
    assert "argument --obstacle: 'cone:c:1' must be box:" in _usage_error(
        ["check-state", "--obstacle", "cone:c:1", "--local"], capsys)
    assert "argument --arg: 'prefix' must be NAME=VALUE" in _usage_error(
        ["urdf", "--arg", "prefix"], capsys)
    req = tmp_path / "req.json"
    req.write_text("[1, 2]")
    # a file's problem in one line, without the usage (issue 38, item 9)
    with pytest.raises(SystemExit) as e:
        main(["plan", "--request", str(req)])
    assert e.value.code == 2
    assert capsys.readouterr().err == \
        f"arduinobot plan: error: argument --request: {req} must hold a JSON object\n"
    assert "argument --workers: must be >= 1, not 0" in _usage_error(
        ["serve", "--workers", "0"], capsys)


def test_flags_that_do_not_go_together_are_usage_errors(capsys, tmp_path):
    traj = tmp_path / "t.json"
    traj.write_text("{}")
    assert _usage_error(["execute", str(traj), "--named", "home", "--sim"], capsys) == \
        "arduinobot execute: error: give TRAJ.json or --named/--request, not both"
    assert "--fast is for --sim" in _usage_error(
        ["execute", str(traj), "--serial", "--fast"], capsys)
    assert "--blend needs --remote" in _usage_error(
        ["execute", "--named", "home", "--sim", "--blend"], capsys)
    assert "--group goes with --named" in _usage_error(
        ["execute", str(traj), "--sim", "--group", "arm"], capsys)
    assert "its model is the service's, not FILE" in _usage_error(
        ["execute", "my.urdf", "--named", "home", "--remote"], capsys)
    assert "at most one TRAJ.json and one model FILE" in _usage_error(
        ["execute", "a.urdf", "b.xacro", "--named", "home", "--sim"], capsys)
    assert "give a goal: --goal, --named" in _usage_error(["plan", "--local"], capsys)
    assert "--package-dir" in _usage_error(["plan", "--named", "home", "--package-dir",
                                            str(tmp_path)], capsys)
    # checked against the robot: the local model's joints and groups
    assert "--goal: 5 values for 3 joints (joint_1, joint_2, joint_3)" in _usage_error(
        ["plan", "--goal", "1,2,3,4,5", "--group", "arm", "--local"], capsys)
    assert "--group 'legs' is not a group of this robot (arm, gripper, all)" in _usage_error(
        ["plan", "--goal", "0.1", "--group", "legs", "--local"], capsys)


def test_the_plan_command_imports_no_planner_machinery(server):
    # the client path of `arduinobot plan` talks to the service: it must not pay for
    # (or need) the planner's libraries
    code = ("import sys\nfrom arduinobot.cli.main import main\n"
            f"rc = main(['plan', '--named', 'reach_left', '--connect', {server.endpoint!r}])\n"
            "heavy = sorted(m for m in ('trimesh', 'numba', 'ompl', 'fcl', 'toppra', "
            "'mujoco', 'scipy', 'matplotlib') if m in sys.modules)\n"
            "print('HEAVY', heavy, rc)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=ROOT)
    assert "HEAVY [] 0" in out.stdout, out.stdout[-2000:] + out.stderr[-2000:]


@pytest.fixture
def fake_instances():
    """Three 'instances' on a real zenoh peer: liveliness tokens, health replies with a
    load each (c never answers health), and fk queryables that say who answered. Loads
    are set by the test through the returned dict."""
    port = free_port()
    s = zenoh.open(zenoh_config(mode="peer", listen=[f"tcp/127.0.0.1:{port}"]))
    loads = {"a": 0.0, "b": 0.0}
    ents = []
    for inst in ("a", "b", "c"):
        ents.append(s.liveliness().declare_token(f"fake/alive/{inst}"))
        ents.append(s.declare_queryable(
            f"fake/instance/{inst}/fk", lambda q, inst=inst: q.reply(
                str(q.key_expr), json.dumps({"request_id": inst}).encode()), complete=True))
        if inst != "c":
            ents.append(s.declare_queryable(
                f"fake/instance/{inst}/health", lambda q, inst=inst: q.reply(
                    f"fake/instance/{inst}/health", json.dumps(
                        {"instance": inst, "load": loads[inst],
                         "workers": [{"pid": 1, "busy": None}] * 2}).encode()),
                complete=True))
    yield f"tcp/127.0.0.1:{port}", loads
    for e in ents:
        e.undeclare()
    s.close()


def test_spread_picks_by_reported_load_then_own_in_flight_then_in_turn(fake_instances):
    endpoint, loads = fake_instances
    with PlannerClient(endpoint, prefix="fake", spread=True, timeout=5) as c:
        assert c.instances(refresh=True) == ("a", "b", "c")
        seen = c.balancer.loads()
        assert seen["a"].load == 0.0 and seen["a"].workers == 2
        assert seen["c"].load == float("inf")  # no health reply: the last resort
        # equal loads take turns; c (unknown load) is never picked while a or b is there
        assert sorted(c.request("fk", {})["request_id"] for _ in range(4)) == \
            ["a", "a", "b", "b"]
        loads["a"] = 1.5
        c.instances(refresh=True)
        assert {c.request("fk", {})["request_id"] for _ in range(4)} == {"b"}
        # what this client has in flight counts: 2 on b (2 workers) weigh 1.0 < 1.5 ...
        with c.balancer.sending("b"), c.balancer.sending("b"):
            assert c.balancer.pick() == "b"
            with c.balancer.sending("b"):  # ... 3 weigh 1.5: a and b tie, they take turns
                assert {c.balancer.pick() for _ in range(4)} == {"a", "b"}
        assert c.balancer.pick(exclude=("a", "b")) == "c"
        assert c.balancer.pick(exclude=("a", "b", "c")) is None


def test_request_payloads_are_strict_json_whichever_encoder_writes_them():
    """orjson writes them; what it would get wrong (NaN as null) or refuses (numpy
    scalars, ints over 64 bits) goes to json, which refuses non-finite numbers."""
    body = {"goal": {"joints": {"joint_1": 0.5}}, 7: [1, 2.25, True], "s": "é"}
    fast = encode_body(body)
    assert b" " not in fast  # orjson's compact form: it took this one
    assert json.loads(fast) == json.loads(json.dumps(body))
    for odd in ({"x": None}, {"x": np.float64(0.25)}, {"x": 2**70}, {None: 1}):
        assert json.loads(encode_body(odd)) == json.loads(json.dumps(odd))
    for bad in (float("nan"), float("inf"), -float("inf"), np.float64("nan")):
        with pytest.raises(ValueError, match="not JSON compliant"):
            encode_body({"joints": {"joint_1": bad}})
    with pytest.raises(TypeError):
        encode_body({"x": {1, 2}})
    assert encode_body(b"{}") == b"{}" and encode_body("{}") == b"{}"
    assert encode_body(None) is None
