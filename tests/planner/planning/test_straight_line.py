"""Straight-line moves (LIN): on the line to 1 mm, within the Pilz Cartesian limits and
every joint limit, certified; refused with the fraction reached where the line cannot go.

The tcp is recomputed here by an independent forward kinematics (scipy rotations over the
model's joint origins and axes, not the planner's numba kernel), and its speed and
acceleration by finite differences on the reply's samples.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from arduinobot.contract.errors import GoalOutOfReach, InvalidRequest, LineInterrupted
from arduinobot.description import load_description
from arduinobot.description.errors import DescriptionError
from arduinobot.description.moveit_config import CartesianLimits, read_cartesian_limits
from arduinobot.planner.kinematics.ik import position_ik
from arduinobot.planner.planning.goals import LineGoal
from arduinobot.planner.planning.lines.straight_line import MAX_DEVIATION
from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
from arduinobot.scene.obstacles import Obstacle
from tests.helpers.fk import tool_frames

START = {"joint_1": 0.3, "joint_2": 0.4, "joint_3": -0.3}


@pytest.fixture(scope="module")
def shipped():
    return MotionPlanner(load_description())


def check_line(description, result, a, b, limits: CartesianLimits, vs: float, as_: float):
    """Every sample on the segment a-b within 1 mm; tcp speed, acceleration (speeding up
    and slowing down) and angular speed within the scaled limits, by finite differences;
    the largest deviation found, which the reply must not understate."""
    traj = result.trajectory
    p, r = tool_frames(description, traj.joint_names, traj.positions)
    d = b - a
    t = np.clip((p - a) @ d / (d @ d), 0.0, 1.0)
    dev = np.linalg.norm(p - (a + t[:, None] * d), axis=1)
    assert dev.max() <= MAX_DEVIATION
    assert result.line.max_deviation >= dev.max() - 1e-9  # measured on a finer grid
    assert np.allclose(p[0], a, atol=1e-9) and np.allclose(p[-1], b, atol=1e-6)
    dt = np.diff(traj.times)
    v = np.diff(p, axis=0) / dt[:, None]
    assert np.linalg.norm(v, axis=1).max() <= limits.max_trans_vel * vs + 1e-9
    acc = np.diff(v, axis=0) / (0.5 * (dt[1:] + dt[:-1]))[:, None]
    u = d / np.linalg.norm(d)
    along = acc @ u
    assert along.max() <= limits.max_trans_acc * as_ + 1e-9
    assert along.min() >= limits.max_trans_dec * as_ - 1e-9
    assert np.linalg.norm(acc, axis=1).max() <= \
        max(limits.max_trans_acc, -limits.max_trans_dec) * as_ + 1e-9
    turn = Rotation.from_matrix(np.swapaxes(r[:-1], 1, 2) @ r[1:]).magnitude() / dt
    assert turn.max() <= limits.max_rot_vel * vs + 1e-9
    rep = result.verification
    assert rep.ok and rep.certified and rep.collision_free
    return float(dev.max())


def start_tcp(mp, start):
    q = np.array([start.get(n, 0.0) for n in mp.joint_names])
    return tool_frames(mp.description, mp.joint_names, [q])[0][0]


def test_line_down_is_straight_and_within_the_limits(shipped):
    a = start_tcp(shipped, START)
    res = shipped.solve(MotionRequest(goal=LineGoal(offset=(0.0, 0.0, -0.1)), start=START))
    dev = check_line(shipped.description, res, a, a + [0, 0, -0.1], CartesianLimits(),
                     1.0, 1.0)
    assert res.planner == "straight line"
    assert res.line.length == pytest.approx(0.1)
    assert res.reached.position_error < 1e-9 and res.reached.within_tolerance
    # the Cartesian limits, not the joints', bound this line: one of them is reached
    assert max(res.line.ratios.values()) > 0.9
    assert dev < 1e-3


def test_scalings_scale_the_cartesian_limits(shipped):
    a = start_tcp(shipped, START)
    b = a + np.array([0.08, 0.05, 0.02])
    res = shipped.solve(MotionRequest(goal=LineGoal(position=tuple(b)), start=START,
                                      velocity_scaling=0.2, acceleration_scaling=0.1))
    check_line(shipped.description, res, a, b, CartesianLimits(), 0.2, 0.1)
    assert res.line.limits["max_trans_vel"] == pytest.approx(0.2)
    assert res.line.limits["max_trans_dec"] == pytest.approx(-0.5)


def test_offset_in_the_tool_frame(shipped):
    q = np.array([START.get(n, 0.0) for n in shipped.joint_names])
    p, r = tool_frames(shipped.description, shipped.joint_names, [q])
    off = np.array([0.0, 0.0, -0.05])
    res = shipped.solve(MotionRequest(goal=LineGoal(offset=tuple(off), frame="tcp"),
                                      start=START))
    check_line(shipped.description, res, p[0], p[0] + r[0] @ off, CartesianLimits(), 1, 1)


def test_a_line_out_of_reach_is_refused_with_its_fraction(shipped):
    a = start_tcp(shipped, START)
    with pytest.raises(LineInterrupted) as e:
        shipped.solve(MotionRequest(goal=LineGoal(offset=(0.0, 2.0, 0.0)), start=START))
    err = e.value
    assert err.code == "LINE_INTERRUPTED"
    assert err.reason in ("out_of_workspace", "joint_limit", "singularity")
    assert 0.0 < err.fraction < 1.0 and err.details["fraction"] == err.fraction
    d = load_description()
    kin = shipped.world(()).kin
    # the fraction is honest: the line is reachable up to it, not much beyond it
    reached = a + err.fraction * np.array([0.0, 2.0, 0.0])
    assert position_ik(kin, d.tcp, reached, joints=("joint_1", "joint_2", "joint_3"))
    if err.reason == "out_of_workspace":
        beyond = a + (err.fraction + 0.05) * np.array([0.0, 2.0, 0.0])
        with pytest.raises(GoalOutOfReach):
            position_ik(kin, d.tcp, beyond, joints=("joint_1", "joint_2", "joint_3"))


def test_a_line_through_an_obstacle_is_refused_not_bent(shipped):
    a = start_tcp(shipped, START)
    b = a + np.array([0.0, 0.0, -0.4])
    box = Obstacle("block", "box", size=(0.3, 0.3, 0.05), xyz=tuple(a + [0.0, 0.0, -0.2]))
    with pytest.raises(LineInterrupted) as e:
        shipped.solve(MotionRequest(goal=LineGoal(position=tuple(b)), start=START,
                                    obstacles=(box,)))
    assert e.value.reason == "collision"
    # the claw meets the block's top (0.175 down the 0.4 m line) before the tcp does
    assert 0.05 < e.value.fraction < 0.45
    assert any("block" in p for p in e.value.details["pairs"])
    # without the block the same line is planned
    res = shipped.solve(MotionRequest(goal=LineGoal(position=tuple(b)), start=START))
    assert res.line.max_deviation <= MAX_DEVIATION


def test_line_goal_fields():
    with pytest.raises(InvalidRequest):
        LineGoal()
    with pytest.raises(InvalidRequest):
        LineGoal(position=(0, 0, 1), offset=(0, 0, 1))
    with pytest.raises(InvalidRequest):
        LineGoal(position=(0, 0, 1), frame="tcp")
    with pytest.raises(InvalidRequest):
        LineGoal(offset=(0, 0, float("nan")))


def test_a_moving_start_is_not_taken_by_a_line(shipped):
    with pytest.raises(InvalidRequest) as e:
        shipped.solve(MotionRequest(goal=LineGoal(offset=(0, 0, -0.05)), start=START,
                                    start_velocity={"joint_1": 0.1}))
    assert e.value.field == "goal"


# -- the Cartesian limits file ------------------------------------------------------------

def test_cartesian_limits_are_read_and_defaulted(tmp_path: Path):
    assert read_cartesian_limits(None) == CartesianLimits()
    assert "Setup Assistant" in CartesianLimits().source
    f = tmp_path / "pilz_cartesian_limits.yaml"
    f.write_text("cartesian_limits:\n  max_trans_vel: 0.5\n  max_trans_acc: 1.0\n"
                 "  max_trans_dec: -2.0\n  max_rot_vel: 0.8\n")
    lim = read_cartesian_limits(f)
    assert (lim.max_trans_vel, lim.max_trans_acc, lim.max_trans_dec, lim.max_rot_vel) == \
        (0.5, 1.0, -2.0, 0.8)
    assert lim.source == str(f)
    f.write_text("cartesian_limits:\n  max_trans_vel: 0.5\n")
    part = read_cartesian_limits(f)
    assert part.max_trans_vel == 0.5 and part.max_trans_acc == 2.25
    assert "max_trans_acc" in part.source
    f.write_text("cartesian_limits:\n  max_trans_dec: 5.0\n")
    with pytest.raises(DescriptionError):
        read_cartesian_limits(f)


def test_lin_on_the_course_workspace(course_ws):
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})
    assert d.config.cartesian_limits == \
        course_ws.moveit_pkg / "config" / "pilz_cartesian_limits.yaml"
    lim = read_cartesian_limits(d.config.cartesian_limits)
    assert (lim.max_trans_vel, lim.max_trans_acc, lim.max_trans_dec, lim.max_rot_vel) == \
        (1.0, 2.25, -5.0, 1.57)
    mp = MotionPlanner(d)
    a = start_tcp(mp, START)
    res = mp.solve(MotionRequest(goal=LineGoal(offset=(0.0, 0.0, -0.05)), start=START))
    # joint_limits.yaml scales to 0.1 by default: so do the Cartesian limits
    vs, as_ = mp.scaling(MotionRequest(goal=LineGoal(offset=(0.0, 0.0, -0.05))))
    assert (vs, as_) == (0.1, 0.1)
    check_line(d, res, a, a + [0.0, 0.0, -0.05], lim, vs, as_)
    assert res.line.limits["source"] == str(d.config.cartesian_limits)


# -- through a real serve ------------------------------------------------------------------

@pytest.mark.slow
def test_line_and_pose_goals_through_the_service(client):
    from arduinobot.client import errors

    res = client.plan(goal={"line": {"offset": [0.0, 0.0, -0.05]}}, start=START)
    assert res.planner == "straight line"
    assert res.line["max_deviation"] <= MAX_DEVIATION and res.line["fraction"] == 1.0
    assert res.line["limits"]["max_trans_vel"] == pytest.approx(1.0)
    assert res.reached["within_tolerance"] and res.reached["residuals"]["position"] < 1e-6
    d = load_description()
    p, _ = tool_frames(d, res.joint_names, res.positions[[0, -1]])
    assert np.allclose(p[1] - p[0], [0.0, 0.0, -0.05], atol=1e-6)
    with pytest.raises(errors.LineInterrupted) as e:
        client.plan(goal={"line": {"offset": [0.0, 2.0, 0.0]}}, start=START)
    assert 0.0 < e.value.details["fraction"] < 1.0
    with pytest.raises(errors.OrientationNotControllable) as e:
        client.plan(goal={"position": p[1].tolist(), "orientation": {"rpy": [np.pi, 0, 0]}},
                    start=START)
    assert {tuple(a["joints"]) for a in e.value.details["controllable_axes"]} == \
        {("joint_1",), ("joint_2", "joint_3")}


def test_the_plan_command_takes_lines_and_tolerances(capsys):
    from arduinobot.cli.argtypes import UsageError
    from arduinobot.cli.commands.plan import build_request
    from arduinobot.cli.main import build_parser, main

    robot = {"joints": [{"name": n} for n in ("joint_1", "joint_2", "joint_3", "joint_4")]}

    def req(*argv):
        return build_request(build_parser().parse_args(["plan", *argv]), robot)

    assert req("--line", "0,1,1.2")["goal"] == {"line": {"position": [0.0, 1.0, 1.2]}}
    assert req("--offset", "0,0,-0.05", "--frame", "tcp")["goal"] == \
        {"line": {"offset": [0.0, 0.0, -0.05], "frame": "tcp"}}
    assert req("--position", "0,1,1.2", "--tolerance", "0.01")["goal"] == \
        {"position": [0.0, 1.0, 1.2], "tolerance": 0.01}
    for bad in (("--line", "0,1,1.2", "--frame", "tcp"), ("--named", "home", "--tolerance", "0.1")):
        with pytest.raises(UsageError):
            req(*bad)
    assert main(["plan", "--offset", "0,0,-0.05", "--start", "0.3,0.4,-0.3", "--local"]) == 0
    out = capsys.readouterr().out
    assert "line: 0.0500 m, largest deviation" in out and "planner straight line" in out
    assert "reached: tcp" in out and "mm from the goal" in out
