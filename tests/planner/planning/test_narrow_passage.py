"""A narrow passage (src/arduinobot/planner/planning/pathfinding/paths.py, room.py): the
shipped arm from joint_1 = 1.2 to -1.2 must cross the wall of tests/helpers/planning_scenes.py
(the plane every such motion passes at joint_1 = 0); :data:`SLOT`'s window lets the arm
through only in a narrow band of poses (:data:`SPLIT`'s, smaller, in none: a real
NO_PATH_FOUND, tests/planner/planning/test_paths.py). The room the search keeps first
(2 mm, :data:`~.paths.ROOM`) must not close the passage: the plan is found, certified and
free when re-checked densely."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pathfinding.paths import PathPlanner, PathRequest
from tests.helpers.planning_scenes import SLOT, SPLIT_GOAL, SPLIT_START


@pytest.fixture(scope="module")
def slot():
    d = load_description(env={})
    return d, CollisionWorld(d), CollisionWorld(d, obstacles=list(SLOT))


def test_the_window_is_a_narrow_passage(slot):
    # of the seeded arm poses at joint_1 = 0 free without the wall, few are free in it:
    # a passage a sampler meets rarely, not an open door
    d, bare, w = slot
    lim = d.robot.position_limits(w.kin.joint_names)
    rng = np.random.default_rng(5)
    qs = rng.uniform(lim[:, 0], lim[:, 1], size=(2000, w.dof))
    qs[:, 0] = 0.0
    qs[:, 3] = 0.0  # the gripper as the start holds it
    free = [q for q in qs if bare.is_valid(q)]
    through = [q for q in free if w.is_valid(q)]
    assert len(free) > 1000
    assert 0 < len(through) < 0.03 * len(free), (len(through), len(free))


@pytest.mark.parametrize("seed", [1, 3])
def test_the_passage_is_planned_and_certified(slot, seed):
    d, _, w = slot
    names = w.kin.joint_names
    start = np.array([SPLIT_START[n] for n in names])
    goal = start.copy()
    goal[:3] = [SPLIT_GOAL[n] for n in names[:3]]
    assert w.is_valid(start) and w.is_valid(goal)
    assert w.first_invalid(interpolate(np.array([start, goal]), 0.01)) >= 0
    # a budget the search never spends here (its slices are counted in iterations, so
    # the seeded result does not depend on the machine's speed)
    r = PathPlanner(w, d).solve(PathRequest(start=start, goal=JointGoal(SPLIT_GOAL),
                                            seed=seed, planning_time=30.0))
    assert not r.straight_line
    assert r.certificate is not None and r.certificate.free
    assert np.allclose(r.path[0], start) and np.allclose(r.path[-1], goal)
    qs = interpolate(r.path, 0.002)
    assert w.first_invalid(qs) == -1
    # it crossed the wall's plane through the window: at joint_1 = 0 in a pose that fits
    k = int(np.argmin(np.abs(qs[:, 0])))
    assert abs(qs[k, 0]) < 0.01 and w.is_valid(qs[k])
