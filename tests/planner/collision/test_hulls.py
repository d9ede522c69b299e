"""Convex-hull distance bounds (src/arduinobot/planner/collision/bounds/hulls.py): never above FCL's exact
distance, on the shipped arm and on the course workspace's CAD links (millimetre meshes
with open edges), against every obstacle shape, nor warm-started from a stale or any
direction; equal to it for convex bodies."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from arduinobot.description import load_description
from arduinobot.planner.collision.bounds.hulls import mesh_hull, separation, warm_bound
from arduinobot.planner.collision.proof.ladder import Ladder
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.obstacles import Obstacle


class _Cache:
    def __init__(self) -> None:
        self.data: dict[tuple[str, str], dict] = {}
        self.loads = 0

    def load(self, kind, key):
        self.loads += 1
        return self.data.get((kind, key))

    def store(self, kind, key, arrays):
        self.data[(kind, key)] = dict(arrays)


# around the arm (1.5 m tall), each in reach of some states
OBSTACLES = [Obstacle("slab", "box", size=(0.4, 0.4, 0.04), xyz=(0.0, 0.9, 0.9)),
             Obstacle("ball", "sphere", radius=0.1, xyz=(0.7, 0.6, 1.2)),
             Obstacle("post", "cylinder", radius=0.06, length=1.5, xyz=(-0.8, 0.3, 0.75))]


def _warm(world: CollisionWorld, q: np.ndarray, p: int, n: np.ndarray) -> float:
    poses = world.kin.link_poses(q)
    a, b = (int(x) for x in world.table.pairs.index[p])
    return warm_bound(*world.hulls, a, world.body_pose(poses, a), b, world.body_pose(poses, b),
                      n)


def _bounds_never_exceed_exact(world: CollisionWorld, seed: int, n: int) -> int:
    # at free states, every checked pair: the hull bound against FCL's exact distance;
    # the warm bound from its direction a step away, and from any direction
    lim = world.description.robot.position_limits()
    rng = np.random.default_rng(seed)
    tight = 0
    for q in rng.uniform(lim[:, 0], lim[:, 1], size=(n, world.dof)):
        if not world.is_valid(q):
            continue
        moved = np.clip(q + rng.normal(0.0, 0.02, world.dof), lim[:, 0], lim[:, 1])
        for p in range(len(world.pair_names)):
            exact = world.pair_distance(q, p)
            direction = np.full(3, np.nan)
            bound, was_exact = Ladder(world, clear=0.0).state_bound(q, p, above=-np.inf,
                                                                  direction=direction)
            assert not was_exact
            assert bound <= exact + 1e-12, (world.pair_names[p], bound, exact)
            tight += bound >= 0.9 * exact > 0
            if not np.isfinite(direction[0]):
                continue  # the hulls touch: no direction
            assert abs(np.linalg.norm(direction) - 1.0) < 1e-12
            # from GJK's own direction the warm bound is at least as good
            assert _warm(world, q, p, direction.copy()) >= bound - 1e-12
            if world.is_valid(moved):
                assert _warm(world, moved, p, direction) <= world.pair_distance(moved, p) + 1e-12
                any_n = rng.normal(size=3)
                assert (_warm(world, moved, p, any_n / np.linalg.norm(any_n))
                        <= world.pair_distance(moved, p) + 1e-12)
    return tight


def test_hull_bounds_never_exceed_the_exact_distance_on_the_shipped_arm(tmp_path):
    rock = trimesh.creation.icosphere(2, radius=0.12)
    rock.vertices[:, 2] *= 0.5  # a flattened, open-topped rock: not a primitive
    rock.update_faces(rock.face_normals[:, 2] < 0.9)
    rock.export(tmp_path / "rock.stl")
    mesh = Obstacle("rock", "mesh", mesh_path=str(tmp_path / "rock.stl"), xyz=(0.6, -0.6, 1.0))
    w = CollisionWorld(load_description(), obstacles=[*OBSTACLES, mesh])
    assert "rock" in {b for pair in w.pair_names for b in pair}
    # not vacuous: most bounds are within 10% of the distance
    assert _bounds_never_exceed_exact(w, 11, 60) > 100


def test_hull_bounds_never_exceed_the_exact_distance_on_cad_links(course_ws):
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})
    w = CollisionWorld(d, obstacles=OBSTACLES)
    assert _bounds_never_exceed_exact(w, 12, 30) > 50


def test_the_ladder_falls_back_to_fcl_where_the_hulls_touch():
    w = CollisionWorld(load_description())
    q = np.zeros(w.dof)
    p = next(i for i, pair in enumerate(w.pair_names) if set(pair) == {"base_link",
                                                                        "claw_support"})
    exact = w.pair_distance(q, p)
    d, was_exact = Ladder(w, clear=0.0).state_bound(q, p, above=exact + 1.0)  # no hull bound is that large
    assert was_exact and d == exact


@pytest.mark.parametrize("seed", range(3))
def test_separation_along_any_direction_is_below_the_distance(seed):
    rng = np.random.default_rng(seed)
    a = trimesh.creation.icosphere(2, radius=0.05)
    b = trimesh.creation.box(extents=(0.1, 0.04, 0.07))
    ta, tb = np.eye(4), np.eye(4)
    ta[:3, :3] = trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3]
    tb[:3, :3] = trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3]
    tb[:3, 3] = rng.normal(size=3) * 0.1 + (0.2, 0, 0)
    pa = a.vertices @ ta[:3, :3].T + ta[:3, 3]
    pb = b.vertices @ tb[:3, :3].T + tb[:3, 3]
    exact = np.min(np.linalg.norm(pa[:, None] - pb[None], axis=2))  # vertex sets
    for n in rng.normal(size=(200, 3)):
        n /= np.linalg.norm(n)
        assert separation(np.asarray(a.vertices), ta, np.asarray(b.vertices), tb, n) \
            <= exact + 1e-12


def test_convex_bodies_get_their_exact_distance():
    # a box obstacle and a sphere obstacle are convex: the bound is their distance
    from arduinobot.planner.collision.bounds.hulls import HullBounds, primitive_hull
    box = Obstacle("b", "box", size=(0.1, 0.2, 0.3))
    ball = Obstacle("s", "sphere", radius=0.05)
    tb = np.eye(4)
    tb[:3, 3] = (0.3, 0.02, -0.01)
    hb = HullBounds([primitive_hull(box), primitive_hull(ball)], np.tile(np.eye(4), (2, 1, 1)))
    assert hb.bound(0, np.eye(4), 1, tb) == pytest.approx(0.3 - 0.05 - 0.05, abs=1e-9)


def test_hulls_are_cached_by_content_and_flat_meshes_get_their_box():
    cache = _Cache()
    v = np.random.default_rng(0).normal(size=(500, 3))
    first = mesh_hull(v, cache)
    again = mesh_hull(v, cache)
    assert len(cache.data) == 1 and np.array_equal(first.vertices, again.vertices)
    # every input point is inside the hull (within its radius) along random directions
    dirs = np.random.default_rng(1).normal(size=(300, 3))
    assert np.all((v @ dirs.T).max(0) <= (first.vertices @ dirs.T).max(0) + first.radius)
    flat = np.c_[np.random.default_rng(2).random((50, 2)), np.zeros(50)]
    tri = mesh_hull(flat[:3])  # three points: qhull refuses, the box stands in
    assert len(tri.vertices) == 8
    assert np.all((flat[:3] @ dirs.T).max(0) <= (tri.vertices @ dirs.T).max(0) + 1e-12)
