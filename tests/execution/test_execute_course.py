"""Issue 27, items 3, 4 and 10, typed as a user of the course's workspace would: the robot
a plan is replayed or executed on is the one it was planned for (the service's, or the
model file given), a trajectory that does not fit its robot is refused naming the joint
and the limit, ``execute`` takes the model file and ``--group`` as ``plan`` does, and a
first twin of a new model says what it is building."""

from __future__ import annotations

import json
import os
import re

import pytest

from tests.helpers.cli import run_cli
from tests.helpers.serve import start_server

GOAL = {"goal": {"joints": {"joint_1": 0.5, "joint_2": 0.3, "joint_3": 0.2}}, "seed": 3}


def _needs(out: str) -> list[str]:
    """The torque column of a `plan --simulate` table: the robot's own dynamics."""
    rows = re.findall(r"^joint_\d\s+\S+ mrad\s+\S+ mrad\s+(\S+) N m", out, re.M)
    assert rows, out
    return rows


def _torques(out: str) -> str:
    """The `execute --sim` report's torque line."""
    line = next((x for x in out.splitlines() if x.startswith("torque needed")), None)
    assert line is not None, out
    return line


@pytest.fixture(scope="module")
def course_model(course_ws):
    """The model options naming the course's robot."""
    return [str(course_ws.xacro), "--package-dir", str(course_ws.src), "--moveit-config",
            str(course_ws.moveit_pkg)]


@pytest.fixture(scope="module")
def course_service(course_model):
    """`arduinobot serve` on the course's robot."""
    srv = start_server(["--workers", "1", *course_model], timeout=240)
    yield srv
    srv.stop()


@pytest.mark.slow
def test_plan_simulate_through_a_service_replays_on_the_services_robot(
        course_service, course_model):
    goal = ["--goal", "joint_1=0.5,joint_2=0.3,joint_3=0.2", "--seed", "3", "--simulate"]
    served = run_cli("plan", *goal, "--connect", course_service.endpoint)
    assert served.returncode == 0, served.stderr
    local = run_cli("plan", *goal, "--local", *course_model)
    assert local.returncode == 0, local.stderr
    shipped = run_cli("plan", *goal, "--local")
    assert shipped.returncode == 0, shipped.stderr
    # the course's arm (a tenth of the shipped one's size) needs other torques: the
    # service's replay is the course robot's, not the shipped twin's
    assert _needs(served.stdout) == _needs(local.stdout)
    assert _needs(served.stdout) != _needs(shipped.stdout)


@pytest.mark.slow
def test_execute_sim_through_a_service_runs_on_the_services_robot(
        course_service, course_model, tmp_path):
    req = tmp_path / "req.json"
    req.write_text(json.dumps(GOAL))
    run = ["--request", str(req), "--sim", "--fast", "--no-publish"]
    served = run_cli("execute", *run, "--connect", course_service.endpoint)
    assert served.returncode == 0, served.stderr
    local = run_cli("execute", *course_model, *run, "--local")
    assert local.returncode == 0, local.stderr
    assert served.stdout.startswith("completed")
    assert _torques(served.stdout) == _torques(local.stdout)


def test_execute_takes_the_model_file_and_a_group_like_plan(course_model):
    # `home` is defined for both the arm and the gripper, as MoveIt's assistant writes it
    run = ["execute", *course_model, "--named", "home", "--sim", "--local", "--fast",
           "--no-publish"]
    ambiguous = run_cli(*run)
    assert ambiguous.returncode == 1 and "group" in ambiguous.stderr
    r = run_cli(*run, "--group", "arm")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("completed")


@pytest.fixture(scope="module")
def shipped_plan(tmp_path_factory):
    from arduinobot.description import load_description
    from arduinobot.planner.planning.goals import NamedGoal
    from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
    res = MotionPlanner(load_description()).solve(MotionRequest(goal=NamedGoal("reach_left"),
                                                                seed=3))
    return {"trajectory": res.trajectory.to_dict()}


@pytest.mark.parametrize("change, joint, limit", [
    ("velocity", "joint_1", "velocity"),  # planned for a faster arm
    ("position", "joint_2", "upper"),  # beyond a position limit
    ("name", "joint_9", None),  # a joint this robot does not have
])
def test_a_trajectory_that_does_not_fit_the_robot_is_refused(shipped_plan, tmp_path, change,
                                                             joint, limit):
    body = json.loads(json.dumps(shipped_plan))
    traj = body["trajectory"]
    names = traj["joint_names"]
    if change == "velocity":  # [rad/s]: far past any joint's limit, at one sample
        traj["points"][len(traj["points"]) // 2]["velocities"][names.index(joint)] = 50.0
    for p in traj["points"]:
        if change == "position":
            p["positions"][names.index(joint)] += 4.0 * p["time_from_start"]
    if change == "name":
        traj["joint_names"] = [*names[:-1], joint]
    f = tmp_path / "traj.json"
    f.write_text(json.dumps(body))
    r = run_cli("execute", str(f), "--sim", "--fast", "--no-publish", "--move-to-start")
    assert r.returncode == 1, r.stdout
    assert "INVALID_TRAJECTORY" in r.stderr and joint in r.stderr, r.stderr
    if limit is not None:
        assert f"{limit} limit" in r.stderr and f'"limit": "{limit}"' in r.stderr


def test_a_first_twin_of_a_model_says_what_it_builds(tmp_path):
    env = {**os.environ, "ARDUINOBOT_CACHE": str(tmp_path / "cache")}
    run = ["execute", "--named", "reach_left", "--sim", "--local", "--fast", "--no-publish"]
    first = run_cli(*run, env=env)
    assert first.returncode == 0, first.stderr
    assert "building the MuJoCo twin" in first.stderr
    assert re.search(r"convex pieces of \w+\.STL", first.stderr), first.stderr
    again = run_cli(*run, env=env)  # kept in the cache: nothing to build, nothing said
    assert again.returncode == 0 and "building the MuJoCo twin" not in again.stderr
