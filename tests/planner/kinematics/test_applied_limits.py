"""The limits a plan was held to, shown where a user looks (issue 27 items 7 and 9):
`info`, the plan summary, the plot and `/description` give the applied (scaled) figures
and where each came from; the shipped model says what its size means for the printed arm."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from arduinobot.cli.commands.plan import summary
from arduinobot.client.replies import PlanReply
from arduinobot.description import load_description
from arduinobot.planner.kinematics.applied_limits import AppliedLimits
from arduinobot.service.plan.bodies import description_body
from arduinobot.viewer.plots import joint_limits, limit_notes, plot_panels
from arduinobot.viewer.trajectory import PlaybackTrajectory
from tests.helpers.serve import REPO

JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4")


@pytest.fixture(scope="module")
def course(course_ws):
    return load_description(course_ws.xacro, env={})


@pytest.fixture(scope="module")
def course_reply(course):
    return description_body(course)


def _plan_body(joints=JOINTS) -> dict:
    """A 1 s motion of joint_1 at 0.8 rad/s peak, sampled at 100 Hz (a smooth bump)."""
    t = np.linspace(0.0, 1.0, 101)
    v = 0.8 * np.sin(np.pi * t) ** 2
    a = 0.8 * np.pi * np.sin(2 * np.pi * t)
    q = np.cumsum(v) * 0.01
    points = [{"positions": [float(q[i]), 0, 0, 0], "velocities": [float(v[i]), 0, 0, 0],
               "accelerations": [float(a[i]), 0, 0, 0], "effort": [0.5, 1.0, 0, 0],
               "time_from_start": float(t[i])} for i in range(len(t))]
    return {"trajectory": {"joint_names": list(joints), "points": points}, "duration": 1.0,
            "path": [[0, 0, 0, 0], [float(q[-1]), 0, 0, 0]], "timing": {"total": 0.01},
            "verification": {"ok": True, "certified": True, "collision_free": True,
                             "min_clearance": 0.01, "worst_overall": {"quantity": "jerk",
                                                                      "ratio": 1.0}},
            "planner": "test", "request_id": "r1"}


def test_description_reply_names_each_limits_origin(course_reply):
    src = course_reply["limit_sources"]
    assert set(src) == set(JOINTS)
    assert src["joint_1"]["velocity"] == "config/joint_limits.yaml"
    assert src["joint_1"]["effort"] == "urdf" and src["joint_1"]["lower"] == "urdf"
    assert src["joint_2"]["acceleration"].startswith("derived: ")
    assert src["joint_2"]["jerk"].startswith("derived: acceleration / 0.1 s")
    assert course_reply["default_scaling"] == {"velocity": 0.1, "acceleration": 0.1}
    assert course_reply["size_note"] is None  # the user's own model: no note on ours


def test_shipped_model_reply_and_info_say_what_its_size_means():
    body = description_body(load_description(env={}))
    note = body["size_note"]
    assert "0.307 m" in note and "0.0307 m" in note and "ten times" in note
    assert "Joint goals are the same" in note and "your own workspace" in note
    assert body["limit_sources"]["joint_1"]["jerk"] == "config/joint_limits.yaml"
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "info"], capture_output=True,
                       text=True, cwd=REPO, env=os.environ | {"ROS_PACKAGE_PATH": ""},
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"size: {note}" in r.stdout


def test_info_shows_the_applied_limits_and_their_origins(course_ws):
    env = {k: v for k, v in os.environ.items()
           if k not in ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH")}
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "info", str(course_ws.xacro)],
                       capture_output=True, text=True, cwd=REPO, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "limits (full -> applied at the default scaling):" in out
    row = next(line for line in out.splitlines() if line.strip().startswith("joint_1 "))
    assert "10 -> 1 " in row  # velocity: joint_limits.yaml's 10 at the default 0.1
    assert "  velocity: joint_limits.yaml x0.1" in out
    assert "  jerk: default (acceleration / 0.1 s) x0.1" in out
    # the course's hobby servos: 54-7500 rad/s^2 derived, each capped at a servo's 40
    assert ("  acceleration: default (from effort, gravity and inertia, capped at 40) x0.1"
            in out)
    assert "  effort: URDF" in out and "  position: URDF" in out
    assert "size:" not in out


def test_plan_summary_shows_the_scaled_limits_jerk_and_where_they_came_from(course_reply):
    res = PlanReply.parse(_plan_body())
    applied = AppliedLimits.from_description_reply(course_reply, res.joint_names, request={})
    text = summary(res, applied)
    header, row = text.splitlines()[1:3]
    assert "|j| peak" in header
    cells = row.split()
    assert cells[0] == "joint_1" and float(cells[2]) == pytest.approx(1.0)  # 10 x 0.1
    jerk_limit = course_reply["limits"]["joint_1"]["jerk"] * 0.1
    assert float(cells[6]) == pytest.approx(jerk_limit, abs=0.01)
    assert float(cells[5]) == pytest.approx(0.8 * np.pi * 2 * np.pi, rel=0.02)  # peak jerk
    assert "  velocity: joint_limits.yaml x0.1" in text
    assert "  jerk: default (acceleration / 0.1 s) x0.1" in text
    assert "(joint_limits.yaml default_*_scaling_factor)" in text
    # a request's own scaling replaces the default, and the summary says so
    own = AppliedLimits.from_description_reply(
        course_reply, res.joint_names, request={"velocity_scaling": 0.5})
    assert own.applied("velocity")[0] == pytest.approx(5.0)
    assert own.applied("acceleration")[0] == pytest.approx(
        course_reply["limits"]["joint_1"]["acceleration"] * 0.1)
    assert "the request, joint_limits.yaml" in summary(res, own)


def test_plot_panels_carry_the_applied_limits_and_their_origins(course):
    t = PlaybackTrajectory.from_json({"joint_names": list(JOINTS), "points": [
        {"positions": [0, 0, 0, 0], "velocities": [0, 0, 0, 0], "accelerations": [0] * 4,
         "effort": [0] * 4, "time_from_start": 0.0},
        {"positions": [0.5, 0, 0, 0], "velocities": [0, 0, 0, 0], "accelerations": [0] * 4,
         "effort": [0] * 4, "time_from_start": 1.0}]})
    from arduinobot.planner.kinematics.applied_limits import applied_limits
    applied = applied_limits(course, JOINTS)
    panels = plot_panels(t, joint_limits(course, JOINTS), notes=limit_notes(applied))
    by = {p.quantity: p for p in panels}
    assert by["velocity"].upper == pytest.approx([1.0] * 4)  # not the full 10
    assert by["velocity"].limit_note == "joint_limits.yaml x0.1"
    assert by["effort"].limit_note == "URDF"
    assert by["acceleration"].limit_note == \
        "default (from effort, gravity and inertia, capped at 40) x0.1"


def test_plan_plot_writes_a_png_with_the_applied_limits(course_reply, tmp_path):
    from arduinobot.cli.commands.plan import plot_trajectory
    res = PlanReply.parse(_plan_body())
    out = tmp_path / "plan.png"
    plot_trajectory(res, AppliedLimits.from_description_reply(course_reply, res.joint_names),
                    str(out))
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
