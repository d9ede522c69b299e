"""Planning from a moving state (src/arduinobot/planner/planning/moving_start.py), in-process and on the wire."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import load_description
from arduinobot.planner.planning.from_rest import FromRest
from arduinobot.planner.planning.goals import NamedGoal
from arduinobot.planner.planning.moving_start import BlendTiming
from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest


@pytest.fixture(scope="module")
def mp():
    return MotionPlanner(load_description())


@pytest.fixture(scope="module")
def moving(mp):
    """A state halfway through a motion to reach_left: fast, accelerating or braking."""
    tr = mp.solve(MotionRequest(goal=NamedGoal("reach_left"), seed=1)).trajectory
    return tr.joint_names, tr.at(0.3 * tr.duration)


@pytest.mark.parametrize("goal", ["reach_forward", "reach_right", "home"])
def test_the_new_trajectory_starts_in_the_moving_state(mp, moving, goal):
    names, p = moving
    assert np.abs(p.velocities).max() > 1.0
    res = mp.solve(MotionRequest(goal=NamedGoal(goal), start=dict(zip(names, p.positions)),
                                 start_velocity=dict(zip(names, p.velocities)),
                                 start_acceleration=dict(zip(names, p.accelerations)),
                                 seed=2))
    tr = res.trajectory
    assert isinstance(tr.timing, BlendTiming)
    assert tr.positions[0] == pytest.approx(p.positions, abs=1e-12)
    assert tr.velocities[0] == pytest.approx(p.velocities, abs=1e-12)
    assert tr.accelerations[0] == pytest.approx(p.accelerations, abs=1e-9)
    assert np.abs(tr.velocities[-1]).max() == 0.0
    goal_q = mp.description.srdf.named_state(goal).values
    assert tr.positions[-1][:3] == pytest.approx([goal_q[n] for n in names[:3]], abs=1e-9)
    assert res.verification.ok  # every limit, and collisions on dense states
    assert res.verification.enforced == ("position", "velocity", "acceleration", "jerk",
                                         "effort")
    assert 0.0 <= tr.timing.shift <= tr.timing.brake_duration
    assert "blend" in res.timing


def test_a_moving_start_never_calls_back_into_the_planner(mp, moving, monkeypatch):
    # the moving start calls the plan from rest below it once; MotionPlanner.solve is
    # entered once, never again from inside (it once was, through a Protocol)
    depth, entered, inner = [0], [], []
    solve, from_rest = MotionPlanner.solve, FromRest.solve

    def outer_spy(self, request):
        depth[0] += 1
        entered.append(depth[0])
        try:
            return solve(self, request)
        finally:
            depth[0] -= 1

    def inner_spy(self, context, request):
        inner.append(request)
        return from_rest(self, context, request)

    monkeypatch.setattr(MotionPlanner, "solve", outer_spy)
    monkeypatch.setattr(FromRest, "solve", inner_spy)
    names, p = moving
    res = mp.solve(MotionRequest(goal=NamedGoal("home"), start=dict(zip(names, p.positions)),
                                 start_velocity=dict(zip(names, p.velocities)), seed=2))
    assert isinstance(res.trajectory.timing, BlendTiming) and res.verification.ok
    assert entered == [1]
    assert len(inner) == 1 and inner[0].start_velocity is None \
        and inner[0].start_acceleration is None


def test_zero_rates_are_the_ordinary_plan(mp):
    a = mp.solve(MotionRequest(goal=NamedGoal("home"), start={"joint_1": 0.4}, seed=3))
    b = mp.solve(MotionRequest(goal=NamedGoal("home"), start={"joint_1": 0.4}, seed=3,
                               start_velocity={"joint_1": 0.0}))
    assert not isinstance(b.trajectory.timing, BlendTiming)
    assert b.trajectory.duration == pytest.approx(a.trajectory.duration)


@pytest.mark.parametrize("field,value,match", [
    ("start_velocity", {"joint_9": 1.0}, "not an actuated joint"),
    ("start_velocity", {"joint_1": 50.0}, "exceeds the velocity limit"),
    ("start_acceleration", {"joint_2": -500.0}, "exceeds the acceleration limit"),
    ("start_velocity", {"joint_1": float("nan")}, "not a finite number"),
])
def test_bad_rates_are_refused_naming_the_field(mp, field, value, match):
    with pytest.raises(InvalidRequest, match=match) as e:
        mp.solve(MotionRequest(goal=NamedGoal("home"), **{field: value}))
    assert e.value.field.startswith(field + ".")


def test_a_brake_past_the_position_limit_is_refused(mp):
    with pytest.raises(InvalidRequest, match="cannot stop within") as e:
        mp.solve(MotionRequest(goal=NamedGoal("home"), start={"joint_1": 1.5},
                               start_velocity={"joint_1": 9.0}))
    assert e.value.field == "start_velocity.joint_1"


def test_on_the_wire():
    from arduinobot.contract import wire
    from arduinobot.service.plan.plan_io import plan_request
    d = load_description()
    req = plan_request(d, wire.decode("plan", wire.encode(
        {"goal": {"named": "home"}, "start_velocity": {"joint_1": 0.5},
         "start_acceleration": {"joint_2": -1.0}})))
    assert req.start_velocity == {"joint_1": 0.5}
    assert req.start_acceleration == {"joint_2": -1.0}
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", wire.encode({"goal": {"named": "home"},
                                         "start_velocity": {"joint_1": "fast"}}))
    assert e.value.field == "start_velocity.joint_1"


@pytest.mark.parametrize("v", [0.2, -0.2])
def test_moving_away_from_the_goal_brakes_within_the_effort_limits(mp, v):
    # a brake checked on 2 ms samples peaked 1.9% over joint_1's effort between them
    # (+0.2 rad/s, away from home), so no blend passed the verifier's finer grid
    r = mp.solve(MotionRequest(goal=NamedGoal("home"), start={"joint_1": 0.3},
                               start_velocity={"joint_1": v}))
    assert r.verification.ok and r.verification.worst["effort"] <= 1.0 + 1e-6
    assert r.trajectory.velocities[0][0] == pytest.approx(v, abs=1e-9)
