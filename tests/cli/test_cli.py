"""The `arduinobot` command line as users type it: negative values, the course's
gripper goal with its mimic, suggestions for typos, messages that say where things went."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

import pytest

from arduinobot.cli.argtypes import Mimic, UsageError, joint_map
from arduinobot.cli.main import build_parser, main
from tests.helpers.serve import REPO


def _usage_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run the CLI expecting a usage error (exit 2); the whole stderr."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    return capsys.readouterr().err


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


# -- negative first values (issues 26.10, 27.2) --------------------------------------------

def test_every_value_flag_of_every_command_takes_a_negative_first_value(capsys):
    # argparse once read '-1.14,-0.6,-0.07' as an unknown option: "expected one argument"
    parser = build_parser()
    taken = refused = 0
    for cmd, sp in _subparsers(parser).items():
        for action in sp._actions:
            if not action.option_strings or action.nargs == 0 or action.choices:
                continue
            flag = action.option_strings[-1]
            # what the command requires besides (execute: a robot, --serial and --driver
            # being one)
            needs = {"execute": ["--sim"], "ik": ["--position", "0,1,1"]}.get(cmd, [])
            argv = [cmd, flag, "-1.14,-0.6,-0.07",
                    *(needs if flag not in ("--serial", "--driver", "--position") else [])]
            try:
                ns, extras = parser.parse_known_args(argv)
            except SystemExit:  # the flag's type refuses the value (--seed is an int)
                err = capsys.readouterr().err
                assert f"argument {flag}: " in err and "expected one argument" not in err, \
                    (cmd, flag, err)
                refused += 1
                continue
            assert extras == [], (cmd, flag, extras)
            assert getattr(ns, action.dest) != action.default, (cmd, flag)
            taken += 1
    assert taken > 40 and refused > 5  # every command's value flags, not a few


def test_goal_start_joints_and_position_take_negative_values_as_typed(capsys):
    # the course's task 1 goal, as its users type it
    ns = build_parser().parse_args(["plan", "--goal", "-1.14,-0.6,-0.07", "--start",
                                    "-0.4,0.3,0.2", "--local"])
    assert ns.goal == (-1.14, -0.6, -0.07) and ns.start == (-0.4, 0.3, 0.2)
    ns = build_parser().parse_args(["ik", "--position", "-0.1,0.9,1.2", "--local"])
    assert ns.position == [-0.1, 0.9, 1.2]
    assert main(["fk", "--joints", "-0.4,0.2,-0.1", "--json", "--local"]) == 0
    reply = json.loads(capsys.readouterr().out)
    assert reply["joints"] == pytest.approx({"joint_1": -0.4, "joint_2": 0.2,
                                             "joint_3": -0.1, "joint_4": 0.0})
    assert main(["check-state", "--joints", "-0.3,0.2", "--padding", "-0", "--local"]) == 0
    assert "joint_1=-0.3000" in capsys.readouterr().out
    assert main(["plan", "--goal", "-1.14,-0.6,-0.07", "--start", "-0.4,0,0.2", "--seed",
                 "3", "--local", "--json", "-"]) == 0
    q = json.loads(capsys.readouterr().out)["trajectory"]["points"]
    assert q[0]["positions"][:3] == pytest.approx([-0.4, 0.0, 0.2], abs=1e-9)
    assert q[-1]["positions"][:3] == pytest.approx([-1.14, -0.6, -0.07], abs=1e-6)


def test_a_negative_goal_through_the_installed_command_line():
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "fk", "--joints",
                        "-0.4,-0.3,0.2", "--link", "base_plate", "--local"],
                       cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "joint_1=-0.4000, joint_2=-0.3000, joint_3=+0.2000" in r.stdout


# -- the course's gripper goal: joint_4 and its mimic (issue 27.6) -------------------------

def test_a_mimics_value_is_checked_against_its_leader_and_dropped():
    mimics = {"joint_5": Mimic("joint_4", -1.0, 0.0)}
    names, every = ("joint_4",), ("joint_1", "joint_2", "joint_3", "joint_4")
    assert joint_map((-0.7, 0.7), names, "--goal", mimics=mimics) == {"joint_4": -0.7}
    assert joint_map({"joint_4": -0.7, "joint_5": 0.7}, (), "--goal", mimics=mimics) == \
        {"joint_4": -0.7}
    # a mimic alone goes to the service, which names its leader
    assert joint_map({"joint_5": 0.7}, (), "--goal", mimics=mimics) == {"joint_5": 0.7}
    with pytest.raises(UsageError, match=r"--goal: joint_5 is a mimic of joint_4 "
                       r"\(joint_5 = -1 \* joint_4 \+ 0\): joint_4=-0.7 gives "
                       r"joint_5=0.7, not 0.5"):
        joint_map((-0.7, 0.5), names, "--goal", mimics=mimics)
    with pytest.raises(UsageError, match=r"3 values for 1 joints \(joint_4; or with "
                       r"their mimics: joint_4, joint_5\)"):
        joint_map((-0.7, 0.7, 0.1), names, "--goal", mimics=mimics, all_joints=every)
    # five values meant for every joint, typed without --group all
    with pytest.raises(UsageError, match=r"5 values for 3 joints .*; for every joint "
                       r"\(joint_1, joint_2, joint_3, joint_4\), add --group all"):
        joint_map((0, 0, 0, -0.7, 0.7), every[:3], "--goal", mimics=mimics,
                  all_joints=every)


def test_the_courses_gripper_goal_plans_on_the_course_workspace(course_ws, capsys):
    model = [str(course_ws.xacro), "--package-dir", str(course_ws.src), "--local"]
    assert main(["plan", "--group", "gripper", "--goal", "-0.7,0.7", "--seed", "1",
                 "--json", "-", *model]) == 0
    reply = json.loads(capsys.readouterr().out)
    names = reply["trajectory"]["joint_names"]
    end = dict(zip(names, reply["trajectory"]["points"][-1]["positions"]))
    assert end["joint_4"] == pytest.approx(-0.7, abs=1e-6)
    err = _usage_error(["plan", "--group", "gripper", "--goal", "-0.7,0.5", *model], capsys)
    assert "joint_5 is a mimic of joint_4" in err and "gives joint_5=0.7, not 0.5" in err
    err = _usage_error(["plan", "--goal", "0.1,0,0,-0.7,0.7", *model], capsys)
    assert "5 values for 3 joints" in err and "add --group all" in err
    # every joint and the mimic, as `check-state` and `--start` take them
    assert main(["check-state", "--joints", "0,0,0,-0.7,0.7", *model]) == 0
    assert "joint_4=-0.7000" in capsys.readouterr().out


def test_the_gripper_goal_with_its_mimic_on_the_shipped_arm(capsys):
    assert main(["check-state", "--joints", "0.2,0,0,-0.5,0.5", "--local"]) == 0
    assert "joint_1=+0.2000" in capsys.readouterr().out
    err = _usage_error(["check-state", "--joints", "0,0,0,-0.5,-0.5", "--local"], capsys)
    assert "--joints: joint_5 is a mimic of joint_4" in err
    assert main(["plan", "--group", "gripper", "--goal", "-0.5,0.5", "--local", "--seed",
                 "2", "--json", "-"]) == 0
    pts = json.loads(capsys.readouterr().out)["trajectory"]["points"]
    assert pts[-1]["positions"][3] == pytest.approx(-0.5, abs=1e-6)


# -- mistyped commands and flags (issue 27.10) ---------------------------------------------

def test_a_mistyped_command_or_choice_suggests_the_closest(capsys):
    err = _usage_error(["paln", "--named", "home"], capsys)
    assert "invalid choice: 'paln', maybe you meant 'plan'?" in err
    err = _usage_error(["serve", "--mode", "peers"], capsys)
    assert "maybe you meant 'peer'?" in err


def test_a_mistyped_flag_shows_its_commands_usage_and_the_closest_flag(capsys):
    err = _usage_error(["plan", "--gaol", "0.1,0.2", "--local"], capsys)
    # the command's usage, not the top-level one
    assert err.startswith("usage: arduinobot plan")
    assert err.splitlines()[-1].startswith("arduinobot plan: error: unrecognized arguments:")
    assert "maybe you meant --goal (not --gaol)?" in err
    err = _usage_error(["fk", "--jionts=0.1", "--local"], capsys)
    assert "maybe you meant --joints (not --jionts)?" in err
    err = _usage_error(["check", "--pacakge-dir", "ws/src"], capsys)
    assert err.startswith("usage: arduinobot check") and "--package-dir" in err


# -- what the command says (issue 27.10) ---------------------------------------------------

def _run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "arduinobot.cli.main", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)


def test_a_second_serve_on_a_busy_port_says_so_before_loading_the_robot(server):
    r = _run("-v", "serve", "--listen", server.endpoint, "--workers", "1")
    assert r.returncode == 1
    port = int(server.endpoint.rsplit(":", 1)[1])
    assert f"arduinobot: serve: {server.endpoint} is in use" in r.stderr
    suggested = r.stderr.split("use --listen tcp/127.0.0.1:", 1)[1].split()[0]
    assert int(suggested) > port
    # refused before any work: no robot loaded, no Zenoh error
    assert "loaded robot" not in r.stderr and "ZError" not in r.stderr, r.stderr


def test_the_ready_line_names_where_to_connect(server):
    assert f"listening on {server.endpoint};" in server.ready_line


def test_the_plan_summary_names_the_robot_and_the_service(server, capsys):
    assert main(["plan", "--goal", "-0.3,0.2,0.1", "--seed", "1", "--connect",
                 server.endpoint]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"robot 'arduinobot', planned by the service at {server.endpoint}\n")
    assert main(["plan", "--goal", "-0.3,0.2,0.1", "--seed", "1", "--local"]) == 0
    assert "robot 'arduinobot', planned in this process (--local)" in capsys.readouterr().out


def test_a_saved_plan_holds_points_though_the_client_asked_for_it_packed(server, tmp_path):
    from arduinobot.client.replies import PlanReply
    traj = tmp_path / "traj.json"
    assert main(["plan", "--goal", "-0.3,0.2,0.1", "--seed", "1", "--connect",
                 server.endpoint, "--json", str(traj)]) == 0
    saved = json.loads(traj.read_text())
    assert "points" in saved["trajectory"] and "packed" not in saved["trajectory"]
    assert PlanReply.parse(saved).positions.shape == (len(saved["trajectory"]["points"]), 4)


def test_written_files_are_announced(tmp_path, capsys):
    traj, csv = tmp_path / "traj.json", tmp_path / "traj.csv"
    assert main(["plan", "--goal", "-0.3,0.2,0.1", "--seed", "1", "--local",
                 "--json", str(traj), "--csv", str(csv)]) == 0
    out = capsys.readouterr().out
    n = len(json.loads(traj.read_text())["trajectory"]["points"])
    assert f"wrote {traj} ({n} samples)\n" in out and f"wrote {csv} ({n} samples)\n" in out
    # with the reply on stdout, stdout stays JSON and the news goes to stderr
    assert main(["plan", "--goal", "-0.3,0.2,0.1", "--seed", "1", "--local",
                 "--json", "-", "--csv", str(csv)]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["trajectory"]["points"]
    assert f"wrote {csv} ({n} samples)" in cap.err


def test_info_prints_each_warning_once(course_ws):
    r = _run("info", str(course_ws.xacro), "--package-dir", str(course_ws.src))
    assert r.returncode == 0, r.stderr
    warning = "link 'rgb_camera_link' <visual> #1: <material> inside <geometry> is ignored"
    assert (r.stdout + r.stderr).count(warning) == 1
    assert f"warning: {course_ws.xacro}: {warning}" in r.stdout
    # the rest of the loader's log still shows with -v
    r = _run("-v", "info", str(course_ws.xacro), "--package-dir", str(course_ws.src))
    assert "loaded robot 'arduinobot'" in r.stderr and warning not in r.stderr


def test_dev_help_lists_its_commands_and_nothing_else():
    r = subprocess.run(["bash", str(REPO / "dev"), "help"], capture_output=True, text=True,
                       timeout=30)
    assert r.returncode == 0
    assert r.stdout.splitlines()[-1].strip().startswith("./dev setup")
    assert "set -euo pipefail" not in r.stdout and "./dev test" in r.stdout


def test_check_state_names_the_ground_and_no_ground_turns_it_off(capsys):
    """The plane the base stands on is an obstacle (issue 38, item 5): a state whose claw
    reaches under it collides with 'ground'; --no-ground (its help says when) checks
    without it."""
    q = "-0.4,-1.2,0.4,-0.2"  # the claw 10 cm clear of everything but the plane
    assert main(["check-state", "--joints", q, "--local"]) == 1
    out = capsys.readouterr().out
    assert "IN COLLISION" in out and "claw_support / ground" in out, out
    assert main(["check-state", "--joints", q, "--no-ground", "--local"]) == 0
    assert "VALID" in capsys.readouterr().out
    for cmd in ("plan", "check-state"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "--no-ground" in text and "z = 0 of the model's root frame" in text
        assert "an arm on a wall" in text, text
