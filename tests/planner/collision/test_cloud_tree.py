"""The cloud body's tree (surface-area splits, arduinobot.planner.collision.cloud_body)
and the nearer-first tree bound (arduinobot.planner.collision.proof.advance): motions
that pass a measured slab a few millimetres above it, or graze into it, are certified
or refused as FCL finds them against a box per raw cell (no tree, no tiles)."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.cloud import Cells, CloudObstacle

# a swing of the base with the fingers 0.10 m below it (bench/cloud.py's arm pose)
Q0 = np.array([0.5, -0.6, -0.6, 0.0])
Q1 = np.array([0.7, -0.6, -0.6, 0.0])


@pytest.fixture(scope="module")
def base() -> CollisionWorld:
    return CollisionWorld(load_description())


def _lowest(world: CollisionWorld, qs: np.ndarray) -> tuple[float, np.ndarray]:
    # the lowest vertex of a moving link over states qs (world z [m]), and where it is
    # (x, y)
    low, at = np.inf, np.zeros(2)
    for q in qs:
        poses = world.kin.link_poses(q)
        for f, (_, pts), still in zip(world.bodies.frames, world.bodies.points,
                                      world.bodies.statics):
            if still:
                continue
            p = pts @ poses[f][:3, :3].T + poses[f][:3, 3]
            i = int(np.argmin(p[:, 2]))
            if p[i, 2] < low:
                low, at = float(p[i, 2]), p[i, :2]
    return low, at


def _slab(top: float, xy: np.ndarray, rng: np.random.Generator) -> Cells:
    # a measured slab: 36 x 36 columns of two cells, some columns one cell, a few empty,
    # its top at ``top`` [m] (the resolution, ~1 cm, chosen so the grid puts it there)
    k = int(round(top / 0.01)) or (1 if top > 0 else -1)
    res = top / k
    c = np.round(xy / res).astype(int)
    i, j = np.meshgrid(np.arange(-18, 18), np.arange(-18, 18), indexing="ij")
    cols = np.column_stack([i.ravel() + c[0], j.ravel() + c[1]])
    cols = cols[rng.uniform(size=len(cols)) > 0.03]
    two = rng.uniform(size=len(cols)) > 0.1
    upper = np.column_stack([cols, np.full(len(cols), k - 1)])
    lower = np.column_stack([cols[two], np.full(two.sum(), k - 2)])
    idx = np.vstack([upper, lower])
    idx = idx[np.lexsort((idx[:, 2], idx[:, 1], idx[:, 0]))]
    return Cells(idx.astype(np.int64), float(res))


def _fcl_truth(world: CollisionWorld, cells: Cells, qs: np.ndarray, *, every: int = 1
               ) -> tuple[bool, float]:
    """Whether a moving link's mesh touches a raw cell box at a state of ``qs``, and the
    least distance [m] at every ``every``-th state: FCL alone, a box per cell in its own
    broad phase."""
    r = cells.resolution
    boxes = [fcl.CollisionObject(fcl.Box(r, r, r), fcl.Transform(np.eye(3), c))
             for c in cells.centers]
    manager = fcl.DynamicAABBTreeCollisionManager()
    manager.registerObjects(boxes)
    manager.setup()
    links = [(fcl.CollisionObject(g, fcl.Transform()), f) for g, f, still in
             zip(world.bodies.geometries, world.bodies.frames, world.bodies.statics)
             if not still]
    touched, least = False, np.inf
    for k, q in enumerate(qs):
        poses = world.kin.link_poses(q)
        for obj, frame in links:
            obj.setTransform(fcl.Transform(poses[frame][:3, :3], poses[frame][:3, 3]))
            data = fcl.CollisionData(request=fcl.CollisionRequest())
            manager.collide(obj, data, fcl.defaultCollisionCallback)
            touched |= data.result.is_collision
            if k % every == 0 and not data.result.is_collision:
                dd = fcl.DistanceData(request=fcl.DistanceRequest())
                manager.distance(obj, dd, fcl.defaultDistanceCallback)
                least = min(least, max(dd.result.min_distance, 0.0))
    return touched, least


@pytest.mark.parametrize("gap_mm", [-4.0, -1.5, 1.5, 4.0, 9.0])
def test_a_pass_over_a_measured_slab_is_decided_as_fcl_finds_it(base, gap_mm):
    rng = np.random.default_rng(int(gap_mm * 10) + 100)
    path = np.array([Q0, Q1])
    qs = interpolate(path, 0.004)
    low, _ = _lowest(base, qs)
    _, xy = _lowest(base, qs[len(qs) // 2:len(qs) // 2 + 1])
    cells = _slab(low - gap_mm / 1000, xy, rng)
    world = base.with_scene(clouds=[CloudObstacle("slab", cells)])
    # the start is free whatever the slab: the motion is what is decided
    touched, least = _fcl_truth(world, cells, qs, every=25)
    cert = Certifier(world).path(path)
    assert touched == (gap_mm < 0)  # the slab is where the case says: this can fail
    assert cert.free == (not touched)
    assert (world.first_invalid(qs) >= 0) == touched
    if cert.free:
        # the certified clearance never exceeds what FCL measures at a sample
        assert 0 < cert.certified_clearance <= least + 1e-6
        assert least < gap_mm / 1000 + 0.01  # a pass within a centimetre, not a far one


def test_the_tree_bound_never_exceeds_fcl_against_the_raw_cells(base):
    # at states 3 cm over the slab, the cloud pairs' tree bounds (the planner's sweep and
    # the certifier read them) stay below FCL's distance to a box per cell, and prove the
    # links apart (a CAD link's leaf boxes are loose: a few millimetres they cannot)
    rng = np.random.default_rng(3)
    qs = interpolate(np.array([Q0, Q1]), 0.05)
    low, _ = _lowest(base, qs)
    _, xy = _lowest(base, qs[len(qs) // 2:len(qs) // 2 + 1])
    cells = _slab(low - 0.03, xy, rng)
    world = base.with_scene(clouds=[CloudObstacle("slab", cells)])
    proven = 0
    for q in qs:
        _, exact = _fcl_truth(world, cells, q[None])
        poses = world._poses_of(q)
        pairs = [tuple(p) for p in world.table.pairs.index
                 if world.body_names[p[1]] == "slab"]
        lb = world._tree_bounds(poses, pairs)
        assert lb.min() <= exact + 1e-9
        proven += lb.min() > 0.0
    assert proven >= len(qs) // 2
