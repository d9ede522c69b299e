"""MotionPlanner end to end: validation by field, verified trajectories, world cache; the
door itself: strategies, the timing profiles' registry, the package's re-exports."""

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import get_args

import numpy as np
import pytest

from arduinobot import planner
from arduinobot.contract.errors import (
    InvalidRequest,
    JointLimitViolation,
    NoPathFound,
    StartInCollision,
)
from arduinobot.planner.planning.from_rest import FromRest
from arduinobot.planner.planning.goals import JointGoal, NamedGoal
from arduinobot.planner.planning.motion import Profile
from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
from arduinobot.planner.timing.profiles import PROFILES
from arduinobot.scene.obstacles import Obstacle
from tests.helpers.planning_scenes import SPLIT, SPLIT_GOAL, SPLIT_START
from tests.helpers.timing import DESC

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
    ("velocity_scaling", {"velocity_scaling": 0.005}),  # below the wire's floor too
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


@pytest.mark.parametrize("moving", [False, True])
def test_a_free_goal_behind_a_wall_is_no_path_found(mp, moving):
    # start and goal free, no motion between them (tests/helpers/planning_scenes.py); from a
    # moving start too (the brake stays clear of the wall, the plan from rest does not)
    req = MotionRequest(goal=JointGoal(SPLIT_GOAL), start=SPLIT_START, obstacles=SPLIT,
                        planning_time=0.2, seed=1,
                        start_velocity={"joint_2": 0.2} if moving else None,
                        ground=False)  # the start reaches under the base's plane
    with pytest.raises(NoPathFound):
        mp.solve(req)


# -- the door ---------------------------------------------------------------------------
ROOT = Path(__file__).resolve().parents[3]


def test_the_timing_profiles_are_one_registry():
    # the request's vocabulary, the registry and the wire's enum are the same names
    schema = json.loads((ROOT / "src/arduinobot/contract/schema/plan_request.json").read_text())
    assert set(PROFILES) == set(get_args(Profile)) == \
        set(schema["properties"]["profile"]["enum"])
    for name, make in PROFILES.items():
        assert make.name == name  # type: ignore[attr-defined]
    # the verifier holds a profile to jerk exactly when the registry says it limits it
    assert {n: p.enforce_jerk for n, p in MotionPlanner(DESC).context.profiles.items()} \
        == {"jerk_limited": True, "time_optimal": False}


def test_the_first_strategy_that_accepts_solves(mp):
    class JointsOnly:
        """Joint goals only, from rest: FromRest's plan under its own name."""

        name = "joints only"

        def __init__(self):
            self.seen = []

        def accepts(self, request):
            return isinstance(request.goal, JointGoal) and request.start_velocity is None

        def solve(self, context, request):
            self.seen.append(request)
            return FromRest().solve(context, request)

    joints = JointsOnly()
    door = MotionPlanner(DESC, strategies=(joints, FromRest()))
    r = door.solve(MotionRequest(goal=GOAL, seed=3))
    assert r.verification.ok and len(joints.seen) == 1
    door.solve(MotionRequest(goal=NamedGoal("home"), seed=3))  # not a joint goal
    assert len(joints.seen) == 1
    # a request no strategy accepts is refused, naming the strategies there are
    only_rest = MotionPlanner(DESC, strategies=(FromRest(),))
    with pytest.raises(InvalidRequest, match="from a moving start .*from rest") as e:
        only_rest.solve(MotionRequest(goal=GOAL, start_velocity={"joint_1": 0.1}))
    assert e.value.field == "goal"


def test_the_package_is_one_light_place_to_import_from():
    # importing planner (as the client does for its errors and ranges) loads none of the
    # planning stack; each re-exported name is the defining module's own object
    heavy = ("numba", "ompl", "fcl", "toppra", "ruckig", "arduinobot.planner.planning")
    out = subprocess.run(
        [sys.executable, "-c", "import sys, arduinobot.planner; "
         f"print([m for m in {heavy!r} if m in sys.modules])"],
        cwd=ROOT, capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    from arduinobot.planner.planning import motion, pipeline
    assert planner.MotionPlanner is pipeline.MotionPlanner
    assert planner.MotionRequest is motion.MotionRequest is pipeline.MotionRequest
    from arduinobot.contract import errors
    assert planner.PlanningError is errors.PlanningError
    for name in planner.__all__:
        assert getattr(planner, name) is not None, name
    assert set(planner.__all__) <= set(dir(planner))
    with pytest.raises(AttributeError):
        planner.NoSuchThing  # noqa: B018
