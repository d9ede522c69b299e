"""MotionPlanner end to end: validation by field, verified trajectories, world cache."""

import math

import numpy as np
import pytest

from planner.errors import InvalidRequest, JointLimitViolation, StartInCollision
from planner.planning.goals import JointGoal
from planner.planning.pipeline import MotionPlanner, MotionRequest
from planner.scene import Obstacle

from .timing_helpers import DESC

GOAL = JointGoal({"joint_1": 1.0, "joint_2": 0.5, "joint_3": -0.4})


@pytest.fixture(scope="module")
def mp():
    return MotionPlanner(DESC)


@pytest.mark.parametrize("profile", ["jerk_limited", "time_optimal"])
def test_solve_returns_a_verified_trajectory(mp, profile):
    r = mp.solve(MotionRequest(goal=GOAL, profile=profile, seed=3, sample_rate=200.0))
    t = r.trajectory
    assert r.verification.ok and r.verification.collision_free
    assert t.joint_names == ("joint_1", "joint_2", "joint_3", "joint_4")
    np.testing.assert_allclose(t.positions[-1], [1.0, 0.5, -0.4, 0.0], atol=1e-12)
    assert t.times[-1] == t.duration and np.diff(t.times).max() <= 1 / 200 + 1e-12
    assert set(r.timing) >= {"validate", "plan", "simplify", "recheck", "parameterise",
                             "verify", "total"}
    assert r.verification.worst["effort"] <= 1 + 1e-6
    assert ("jerk" in r.verification.enforced) == (profile == "jerk_limited")


def test_scaling_slows_down(mp):
    fast = mp.solve(MotionRequest(goal=GOAL, seed=1)).trajectory.duration
    slow = mp.solve(MotionRequest(goal=GOAL, seed=1, velocity_scaling=0.2,
                                  acceleration_scaling=0.2))
    assert slow.trajectory.duration > fast
    assert slow.verification.worst["velocity"] <= 1 + 1e-6


def test_obstacle_path_goes_around_and_world_is_cached(mp):
    wall = (Obstacle("wall", "box", size=(0.1, 0.6, 0.6), xyz=(0.9, 0.9, 1.5)),)
    req = MotionRequest(goal=GOAL, obstacles=wall, seed=2, planning_time=5.0)
    r = mp.solve(req)
    assert r.verification.ok
    w = mp.world(wall)
    assert mp.world((Obstacle("wall", "box", size=(0.1, 0.6, 0.6), xyz=(0.9, 0.9, 1.5),
                              where="obstacles[0]"),)) is w
    # every returned state is free of the obstacle
    ts = np.linspace(0, r.trajectory.duration, 400)
    assert w.first_invalid(r.trajectory.evaluate(ts)[0]) == -1
    # the path's proof and its blends' (not a second proof of the timed curve) certify
    # the motion, and the clearance they report bounds FCL's distance anywhere on it
    assert r.verification.certified and r.verification.collision_free
    qs = r.trajectory.evaluate(np.linspace(0, r.trajectory.duration, 25))[0]
    assert 0 < r.verification.min_clearance <= w.min_clearance(qs)[0] + 1e-9


@pytest.mark.parametrize("field,kwargs", [
    ("planning_time", {"planning_time": 0.0}), ("planning_time", {"planning_time": 61.0}),
    ("velocity_scaling", {"velocity_scaling": 0.0}),
    ("acceleration_scaling", {"acceleration_scaling": 1.5}),
    ("sample_rate", {"sample_rate": 0.5}), ("sample_rate", {"sample_rate": 1001.0}),
    ("profile", {"profile": "fast"}), ("group", {"group": "legs"}),
    ("seed", {"seed": -1}), ("start.joint_9", {"start": {"joint_9": 0.0}}),
    ("start.joint_1", {"start": {"joint_1": math.nan}}),
    ("velocity_scaling", {"velocity_scaling": math.inf}),
])
def test_invalid_fields_are_named(mp, field, kwargs):
    with pytest.raises(InvalidRequest) as e:
        mp.solve(MotionRequest(goal=GOAL, **kwargs))
    assert e.value.field == field


def test_mimic_joint_names_its_leader(mp):
    with pytest.raises(InvalidRequest) as e:
        mp.solve(MotionRequest(goal=GOAL, start={"joint_5": 0.1}))
    assert e.value.field == "start.joint_5" and "joint_4" in str(e.value)


def test_start_outside_limits(mp):
    with pytest.raises(JointLimitViolation) as e:
        mp.solve(MotionRequest(goal=GOAL, start={"joint_4": 0.5}))
    assert e.value.joint == "joint_4" and e.value.field == "start.joint_4"


def test_start_in_collision(mp):
    box = (Obstacle("box", "box", size=(0.3, 0.3, 0.3), xyz=(0.0, 0.0, 1.3)),)
    with pytest.raises(StartInCollision):
        mp.solve(MotionRequest(goal=GOAL, obstacles=box))
