"""A cloud's cells as one collision body (arduinobot.planner.collision.cloud_body): its
geometry against the cell boxes, and plans around a pillar measured as a noisy cloud,
re-checked by FCL with a box per kept cell."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.cloud_body import (
    TREE_LEAF_CELLS,
    cell_boxes,
    cell_tree,
    exposed_faces,
    near_robot,
    robot_surface,
    surface_spacing,
)
from arduinobot.planner.collision.cloud_tiles import cell_geometry
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pathfinding.paths import PathPlanner, PathRequest
from arduinobot.scene.cloud import Cells, CloudObstacle, finite_points
from arduinobot.scene.cloud_filter import kept_cells, near_surface


def _box_distance(points: np.ndarray, cells: Cells) -> np.ndarray:
    # distance of each point to the nearest cell box, by numpy (no FCL)
    lo = cells.index * cells.resolution
    hi = lo + cells.resolution
    gap = np.maximum(np.maximum(lo[None] - points[:, None], points[:, None] - hi[None]), 0)
    return np.linalg.norm(gap, axis=2).min(axis=1)


@pytest.fixture(scope="module")
def blob() -> Cells:
    rng = np.random.default_rng(5)
    idx = np.unique(rng.integers(0, 6, (120, 3)), axis=0)
    return Cells(idx, 0.02)


def test_the_exposed_faces_measure_the_union_of_the_boxes(blob):
    v, f = exposed_faces(blob)
    m = fcl.BVHModel()
    m.beginModel(len(v), len(f))
    m.addSubModel(v, f.astype(np.int32))
    m.endModel()
    body = fcl.CollisionObject(m, fcl.Transform())
    rng = np.random.default_rng(6)
    pts = rng.uniform(-0.05, 0.17, (400, 3))
    expect = _box_distance(pts, blob)
    outside = expect > 1e-4
    assert outside.sum() > 100
    probe = fcl.CollisionObject(fcl.Sphere(1e-9), fcl.Transform())
    got = []
    for p in pts[outside]:
        probe.setTranslation(p)
        got.append(fcl.distance(probe, body, fcl.DistanceRequest(), fcl.DistanceResult()))
    np.testing.assert_allclose(got, expect[outside], atol=1e-6)
    # a face between two occupied cells is inside the union: never exposed
    assert len(f) < 12 * len(blob)


def _cells_of_boxes(lo: np.ndarray, hi: np.ndarray) -> list[tuple[int, int, int]]:
    # every cell (integer corner) inside boxes lo-hi (integer corners), with repeats
    out = []
    for a, b in zip(lo, hi):
        g = np.mgrid[a[0]:b[0], a[1]:b[1], a[2]:b[2]].reshape(3, -1).T
        out.extend(map(tuple, g.tolist()))
    return out


def test_the_cells_joined_into_boxes_are_exactly_their_union(blob):
    lo, size = cell_boxes(blob)
    assert len(lo) < len(blob) and (size >= 1).all()
    cells = _cells_of_boxes(lo, lo + size)
    assert len(cells) == len(blob)  # no cell in two boxes
    assert set(cells) == {tuple(r) for r in blob.index.tolist()}
    # a pillar's hollow sides (runs along z) join into a few boxes
    ring = [(i, j, k) for i in range(5) for j in range(5) for k in range(40)
            if i in (0, 4) or j in (0, 4)]
    lo, size = cell_boxes(Cells(np.array(sorted(ring)), 0.01))
    assert len(lo) <= 4 and size.prod(axis=1).sum() == len(ring)
    # at most `longest` cells along any axis, still exactly the union
    lo, size = cell_boxes(Cells(np.array(sorted(ring)), 0.01), longest=3)
    assert size.max() <= 3 and size.prod(axis=1).sum() == len(ring)
    assert set(_cells_of_boxes(lo, lo + size)) == set(ring)


def test_the_tree_leaves_are_the_joined_boxes(blob):
    t = cell_tree(blob)
    leaves = t.left < 0
    corner, size = cell_boxes(blob, longest=TREE_LEAF_CELLS)
    assert size.max() <= TREE_LEAF_CELLS
    assert leaves.sum() == len(corner) and len(t.center) == 2 * len(corner) - 1
    lo = np.round((t.center[leaves] - t.half[leaves]) / blob.resolution).astype(int)
    hi = np.round((t.center[leaves] + t.half[leaves]) / blob.resolution).astype(int)
    cells = _cells_of_boxes(lo, hi)
    assert sorted(cells) == sorted(map(tuple, blob.index.tolist()))
    # every node's box holds its children's
    for n in np.flatnonzero(~leaves):
        for c in (t.left[n], t.right[n]):
            assert (t.center[c] - t.half[c] >= t.center[n] - t.half[n] - 1e-12).all()
            assert (t.center[c] + t.half[c] <= t.center[n] + t.half[n] + 1e-12).all()
    geom, _, hull = cell_geometry(blob)
    corners = np.vstack([blob.index, blob.index + 1]) * blob.resolution
    assert hull.vertices.min() <= corners.min() + 1e-12
    assert hull.vertices.max() >= corners.max() - 1e-12


START = np.array([1.2, -0.6, -0.6, 0.0])
GOAL = JointGoal({"joint_1": -1.2, "joint_2": -0.6, "joint_3": -0.6})
RES = 0.02


def _box_surface(rng, size, center, n) -> np.ndarray:
    size = np.asarray(size)
    p = rng.uniform(-0.5, 0.5, (n, 3)) * size
    ax = rng.integers(0, 3, n)
    p[np.arange(n), ax] = np.sign(rng.uniform(-1, 1, n)) * size[ax] / 2
    return p + center


@pytest.fixture(scope="module")
def scene():
    """A table under the arm (its fingers reach 0.10 m below the base) and a pillar in its way, measured with 3 mm of noise, NaN
    holes and points on the arm itself at the start state; kept as cells after the
    self-filter at the start state."""
    d = load_description()
    base = CollisionWorld(d)
    rng = np.random.default_rng(7)
    table = np.column_stack([rng.uniform(-1.2, 1.2, 60_000), rng.uniform(-1.2, 1.2, 60_000),
                             np.full(60_000, -0.15)])
    pillar = _box_surface(rng, (0.15, 0.15, 3.0), (0.0, 0.9, 0.6), 60_000)
    poses = base.kin.link_poses(START)
    on_arm = np.vstack([pts @ poses[f][:3, :3].T + poses[f][:3, 3]
                        for f, (_, pts) in zip(base.bodies.frames, base.bodies.points)])
    pts = np.vstack([table, pillar, on_arm]) + rng.normal(0, 0.003, (120_000 + len(on_arm), 3))
    pts[rng.choice(len(pts), 5000, replace=False)] = np.nan
    decoded = finite_points(pts)
    spacing = surface_spacing(RES)
    cells, counts = kept_cells(decoded.points, RES, dropped=decoded.dropped,
                               surface=robot_surface(base, START, spacing=spacing),
                               surface_spacing=spacing)
    world = base.with_scene(clouds=[CloudObstacle("camera", cells)])
    return d, world, cells, counts, len(on_arm)


def _fcl_contacts(world: CollisionWorld, cells: Cells, qs: np.ndarray) -> int:
    """States of ``qs`` where a link's mesh touches a box of a kept cell: FCL alone,
    a box per cell in FCL's own broad phase, not the world's geometry or trees."""
    r = cells.resolution
    boxes = [fcl.CollisionObject(fcl.Box(r, r, r), fcl.Transform(np.eye(3), c))
             for c in cells.centers]
    manager = fcl.DynamicAABBTreeCollisionManager()
    manager.registerObjects(boxes)
    manager.setup()
    links = [fcl.CollisionObject(g, fcl.Transform()) for g in world.bodies.geometries]
    hit = 0
    for q in qs:
        poses = world.kin.link_poses(q)
        touched = False
        for obj, frame in zip(links, world.bodies.frames):
            obj.setTransform(fcl.Transform(poses[frame][:3, :3], poses[frame][:3, 3]))
            data = fcl.CollisionData(request=fcl.CollisionRequest())
            manager.collide(obj, data, fcl.defaultCollisionCallback)
            touched |= data.result.is_collision
        hit += touched
    return hit


def test_points_on_the_arm_are_filtered_not_a_start_in_collision(scene):
    _, world, cells, counts, n_arm = scene
    assert counts.dropped == 5000
    assert counts.robot >= 0.9 * n_arm  # the arm's points (and the table under its base)
    assert counts.kept + counts.robot + counts.objects + counts.dropped == counts.points
    assert world.is_valid(START)
    assert _fcl_contacts(world, cells, START[None]) == 0


def test_plans_go_around_the_measured_pillar(scene):
    d, world, cells, _, _ = scene
    goal = np.array([-1.2, -0.6, -0.6, 0.0])
    straight = interpolate(np.array([START, goal]), 0.002)
    assert world.first_invalid(straight) >= 0
    assert _fcl_contacts(world, cells, straight) > 0  # the check below can fail
    r = PathPlanner(world, d).solve(PathRequest(start=START, goal=GOAL, seed=7))
    assert not r.straight_line
    cert = Certifier(world).path(r.path)
    assert cert.free and cert.certified_clearance > 0
    assert _fcl_contacts(world, cells, interpolate(r.path, 0.002)) == 0


def test_near_robot_finds_the_cells_near_surface_finds(scene):
    # the link-frame search against the world-frame one on the robot's moved samples
    _, world, _, _, _ = scene
    rng = np.random.default_rng(9)
    q = np.array([0.4, -0.3, 0.5, 0.2])
    idx = np.unique(rng.integers(-30, 30, (20_000, 3)), axis=0)
    cells = Cells(idx, 0.01)
    spacing = surface_spacing(0.01)
    expect = near_surface(cells, robot_surface(world, q, spacing=spacing), 0.02)
    got = near_robot(world, q, cells, 0.02, spacing=spacing)
    assert 100 < expect.sum() < len(cells) - 100  # some cells each way: it could fail
    np.testing.assert_array_equal(got, expect)
