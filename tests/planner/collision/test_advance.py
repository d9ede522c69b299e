"""Conservative advancement: its two bounds hold, and sweeping equals checking every state."""

import fcl
import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.description.meshes import shape_mesh
from arduinobot.planner.collision.proof.advance import tree_lower_bound
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.obstacles import AttachedObject, Obstacle
from tests.helpers.fcl_bodies import fcl_objects, place


@pytest.fixture(scope="module")
def world():
    return CollisionWorld(load_description(), obstacles=[
        Obstacle("table", "box", size=(0.6, 1.2, 0.05), xyz=(0, 1.0, 0.6)),
        Obstacle("post", "cylinder", radius=0.05, length=2.0, xyz=(0.6, 0.6, 1.0))])


def _vertices(w, body):
    link = w.body_names[body]
    return np.concatenate([shape_mesh(s).vertices for s in w.description.robot.links[link].collisions])


def _common_frame(w, a, b):
    robot = w.description.robot
    frame = w.table.bodies.frame
    paths = [robot.link_path(w.body_names[x]) if frame[x] >= 0 else () for x in (a, b)]
    k = 0
    while k < min(map(len, paths)) and paths[0][k].name == paths[1][k].name:
        k += 1
    return w.kin.link_index[paths[0][k - 1].child] if k else 0


def test_pair_weights_bound_relative_motion(world):
    # in the frame both bodies hang from, a's points move at most wa, b's at most wb:
    # their distance changes by at most wa + wb <= weight . |dq|
    lim = world.description.robot.position_limits()
    rng = np.random.default_rng(5)
    checked = 0
    frame = world.table.bodies.frame
    for p, (a, b) in enumerate(world.table.pairs.index):
        c = _common_frame(world, a, b)
        pts = [_vertices(world, x)[::5] if frame[x] >= 0 else np.zeros((1, 3))
               for x in (a, b)]
        for _ in range(20):
            q0, q1 = rng.uniform(lim[:, 0], lim[:, 1], size=(2, 4))
            moved = {0: [], 1: []}
            for q in (q0, q1):
                poses = world.kin.link_poses(q)
                inv_c = np.linalg.inv(poses[c])
                for k, x in enumerate((a, b)):
                    rel = inv_c @ world.body_pose(poses, x)
                    moved[k].append(pts[k] @ rel[:3, :3].T + rel[:3, 3])
            disp = sum(np.max(np.linalg.norm(m[1] - m[0], axis=1)) for m in moved.values())
            bound = world.table.pairs.weight[p] @ np.abs(q1 - q0)
            assert disp <= bound + 1e-9
            checked += 1
    assert checked > 200


def test_tree_bound_never_exceeds_fcl_distance(world):
    lim = world.description.robot.position_limits()
    qs = np.random.default_rng(8).uniform(lim[:, 0], lim[:, 1], size=(40, 4))
    f = world.forest
    objs = fcl_objects(world)
    stack, gaps, scratch = np.empty((4096, 2), np.int64), np.empty(4096), np.empty((8, 3, 3))
    positive = 0
    for q in qs:
        poses = world.kin.link_poses(q)
        for a, b in world.table.pairs.index:
            ta, tb = world.body_pose(poses, a), world.body_pose(poses, b)
            lb = tree_lower_bound(ta, f.root[a], tb, f.root[b], f.center, f.axes, f.half,
                                  f.left, f.right, 0.0, np.inf, stack, gaps, scratch)
            place(world, objs, poses, a, b)
            d = fcl.distance(objs[a], objs[b], fcl.DistanceRequest(),
                             fcl.DistanceResult())
            assert lb <= max(d, 0.0) + 1e-9
            positive += lb > 0.01
    assert positive > 100  # the bound is not trivially zero


@pytest.mark.parametrize("padding", [0.0, 0.01])
def test_sweep_decides_every_state_like_single_checks(padding):
    d = load_description()
    w = CollisionWorld(d, padding=padding,
                       obstacles=[Obstacle("table", "box", size=(0.6, 1.2, 0.05),
                                           xyz=(0, 1.0, 0.6))])
    lim = d.robot.position_limits()
    rng = np.random.default_rng(11)
    blocked = 0
    for _ in range(12):
        a, b = rng.uniform(lim[:, 0], lim[:, 1], size=(2, 4))
        qs = interpolate(np.array([a, b]), 0.01)
        valid = np.array([w.is_valid(q) for q in qs])
        expect = int(np.argmin(valid)) if not valid.all() else -1
        assert w.first_invalid(qs) == expect
        # a state is only skipped where no pair can be in contact
        cand = w.sweep_candidates(qs)
        assert np.all(cand.any(axis=1)[~valid])
        blocked += expect >= 0
    assert 0 < blocked < 12


def test_a_world_sharing_the_robot_gets_the_weights_of_one_built_afresh(world):
    # the robot's links' reach is computed once and kept with its bodies: a later world
    # (other obstacles, a carried box whose reach is its own) must get exactly the
    # weights a world built from nothing gets
    obstacles = [Obstacle("shelf", "box", size=(0.3, 0.3, 0.02), xyz=(0.4, -0.3, 0.9))]
    held = [AttachedObject(Obstacle("held", "box", size=(0.04, 0.04, 0.1)),
                           world.description.tcp.parent_link)]
    shared = world.with_scene(obstacles, attached=held)
    fresh = CollisionWorld(load_description(), obstacles=obstacles, attached=held)
    assert shared.table.pair_names == fresh.table.pair_names
    assert any("held" in pair for pair in shared.table.pair_names)  # past the links
    np.testing.assert_array_equal(shared.table.pairs.weight, fresh.table.pairs.weight)
