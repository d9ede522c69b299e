"""Room kept per pair (src/arduinobot/planner/planning/pathfinding/room.py): on the course-like workspace (CAD
meshes, its camera on the base), detours keep 2 mm for every pair that has it at both
ends, also when one pair cannot have it anywhere (a shim 1.5 mm under the turntable,
as the course's camera sits by its base plate): that pair loses the room alone."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pathfinding.paths import PLAN_STEP, ROOM, PathPlanner, PathRequest
from arduinobot.planner.planning.pathfinding.room import Guarded, short_of_room
from arduinobot.scene.obstacles import Obstacle

BALL = Obstacle("ball", "sphere", radius=0.15, xyz=(0.5, 0.5, 0.9))
# under the turntable (base_plate, z >= 0.314 m), above the base (z <= 0.309 m): every
# joint_1 motion turns the plate 1.5 mm past it
SHIM = Obstacle("shim", "box", size=(0.05, 0.04, 0.0025), xyz=(0.12, 0.0, 0.31125))


@pytest.fixture(scope="module")
def course(course_ws):
    return load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})


def _detours(w: CollisionWorld, n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    # seeded arm motions whose straight line collides (the gripper closed)
    lim = w.description.robot.position_limits(w.kin.joint_names)
    rng = np.random.default_rng(seed)
    out: list[tuple[np.ndarray, np.ndarray]] = []
    while len(out) < n:
        a, b = rng.uniform(lim[:, 0], lim[:, 1]), rng.uniform(lim[:, 0], lim[:, 1])
        a[3:] = b[3:] = 0.0
        if w.is_valid(a) and w.is_valid(b) and \
                w.first_invalid(interpolate(np.array([a, b]), 0.002)) >= 0:
            out.append((a, b))
    return out


def _kept_and_short(w: CollisionWorld, path: np.ndarray) -> tuple[float, set]:
    # the smallest exact distance, over the path's checked states, of the pairs that
    # have the room at both ends; and the pairs that do not
    qs = interpolate(path, PLAN_STEP)
    worst, short = np.inf, set()
    for p, name in enumerate(w.pair_names):
        if min(w.pair_distance(path[0], p), w.pair_distance(path[-1], p)) < w.padding + ROOM:
            short.add(name)
            continue
        worst = min(worst, min(w.pair_distance(q, p) for q in qs))
    return worst, short


@pytest.mark.parametrize("obstacles", [(BALL,), (BALL, SHIM)], ids=["ball", "ball+shim"])
def test_detours_keep_the_room_wherever_the_ends_do(course, obstacles):
    w = CollisionWorld(course, obstacles=list(obstacles))
    assert "rgb_camera_link" in w.kin.link_names  # the workspace's camera is there
    pp = PathPlanner(w, course)
    for i, (a, b) in enumerate(_detours(w, 3, seed=1)):
        res = pp.solve(PathRequest(start=a, goal=JointGoal(dict(zip(w.kin.joint_names[:3],
                                                                    b[:3]))), seed=i))
        assert not res.straight_line and res.certificate is not None
        assert res.certificate.free
        worst, short = _kept_and_short(w, res.path)
        # every pair that has the room at both ends keeps it at every checked state
        assert worst >= w.padding + ROOM, (i, worst)
        if SHIM in obstacles:
            assert ("base_plate", "shim") in short  # it never has it: it lost it alone
        else:
            assert not short


def test_a_pair_short_of_room_is_checked_at_the_clearance(course):
    w = CollisionWorld(course, obstacles=[BALL, SHIM])
    pp = PathPlanner(w, course)
    joints = pp.group_joints("arm")
    q = np.zeros(w.dof)
    # the trees doubt more pairs than the exact distance finds short
    exact = short_of_room(w, pp.roomy(joints), [q], ROOM)
    assert exact == (("base_plate", "shim"),)
    assert set(exact) <= set(short_of_room(w, pp.roomy(joints), [q], ROOM, exact=False))
    g = pp.guarded(joints, exact)
    assert isinstance(g, Guarded) and pp.guarded(joints, exact) is g  # built once
    assert g.is_valid(q) and not pp.roomy(joints).is_valid(q)
    # the guard still refuses the plate on the shim: lifting the shim into the plate's
    # way collides in both the exact world and the guarded one, at the same state
    w2 = CollisionWorld(course, obstacles=[BALL, Obstacle(
        "shim", "box", size=(0.05, 0.04, 0.006), xyz=(0.12, 0.0, 0.3125))])
    pp2 = PathPlanner(w2, course)
    g2 = pp2.guarded(joints, exact)
    qs = np.zeros((5, w.dof))
    qs[:, 0] = np.linspace(-1.0, 1.0, 5)
    assert not w2.table.fixed_hits  # clear of the base: the plate is what it hits
    assert w2.first_invalid(qs) == 0 and g2.first_invalid(qs) == 0
    assert not g2.is_valid(q)
