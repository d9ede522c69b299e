"""Part hulls (src/arduinobot/planner/collision/bounds/parts.py): their union holds every mesh's surface, their
bound never exceeds FCL's exact distance on the course workspace's CAD links (concave,
millimetre meshes with open edges and long slivers), they come back from the cache,
and a convex mesh keeps its hull alone."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull, QhullError

from arduinobot.description import load_description
from arduinobot.description.meshes import shape_mesh
from arduinobot.planner.collision.bounds.gjk import gjk_direction
from arduinobot.planner.collision.bounds.hulls import mesh_hull
from arduinobot.planner.collision.bounds.parts import PartBounds, Parts, build_parts, mesh_parts
from arduinobot.planner.collision.proof.ladder import Ladder
from arduinobot.planner.collision.world import CollisionWorld


class _Cache:
    def __init__(self) -> None:
        self.data: dict[tuple[str, str], dict] = {}

    def load(self, kind, key):
        return self.data.get((kind, key))

    def store(self, kind, key, arrays):
        self.data[(kind, key)] = {k: np.array(v) for k, v in arrays.items()}


# the course links the claw and the fingers come near (base_link: 54k triangles, a
# hollow the claw reaches into)
PAIRS = [("base_link", "claw_support"), ("base_link", "gripper_left"),
         ("base_link", "gripper_right"), ("base_link", "forward_drive_arm"),
         ("base_link", "horizontal_arm"), ("forward_drive_arm", "claw_support"),
         ("gripper_right", "gripper_left")]


@pytest.fixture(scope="module")
def course(course_ws):
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})
    return CollisionWorld(d)


def _mesh(world: CollisionWorld, link: str) -> trimesh.Trimesh:
    shapes = world.description.robot.links[link].collisions
    meshes = [shape_mesh(s, element=link) for s in shapes]
    return meshes[0] if len(meshes) == 1 else trimesh.util.concatenate(meshes)


def _inside_some_part(parts: Parts, points: np.ndarray) -> np.ndarray:
    # per point: whether some part's hull (grown by its radius) holds it
    held = np.zeros(len(points), bool)
    for i in range(parts.count):
        v = parts.vertices[parts.offsets[i]:parts.offsets[i + 1]]
        try:
            eq = ConvexHull(v).equations  # unit outward normals n, offsets d: n.x + d <= 0
        except QhullError:  # a flat cluster: the builder gave its (flat) box
            lo, hi = v.min(axis=0) - parts.radii[i], v.max(axis=0) + parts.radii[i]
            held |= ((points >= lo - 1e-12) & (points <= hi + 1e-12)).all(axis=1)
            continue
        held |= (points @ eq[:, :3].T + eq[:, 3]).max(axis=1) <= parts.radii[i] + 1e-12
    return held


def test_the_parts_hold_every_vertex_and_surface_point_of_a_concave_cad_link(course):
    mesh = _mesh(course, "base_link")
    parts = build_parts(mesh.vertices, mesh.faces)
    assert parts.count > 16  # concave: split
    v = np.asarray(mesh.vertices, float)
    assert _inside_some_part(parts, v).all()
    # points inside the triangles too (a triangle's pieces may lie in different parts)
    rng = np.random.default_rng(3)
    tri = v[mesh.faces[rng.integers(0, len(mesh.faces), 3000)]]
    w = rng.dirichlet(np.ones(3), size=len(tri))
    assert _inside_some_part(parts, np.einsum("tk,tkj->tj", w, tri)).all()
    # every node's sphere holds the parts under it
    for node in range(len(parts.left)):
        stack, under = [node], []
        while stack:
            n = stack.pop()
            if parts.part[n] >= 0:
                under.append(parts.part[n])
            else:
                stack += [parts.left[n], parts.right[n]]
        pts = np.concatenate([parts.vertices[parts.offsets[i]:parts.offsets[i + 1]]
                              for i in under])
        assert np.linalg.norm(pts - parts.centers[node], axis=1).max() <= parts.reach[node]


def test_part_bounds_never_exceed_the_exact_distance_on_cad_links(course):
    lim = course.description.robot.position_limits()
    rng = np.random.default_rng(12)
    pairs = [course.pair_names.index(p) for p in PAIRS if p in course.pair_names]
    assert len(pairs) >= 4  # (the course's SRDF disables some)
    near = tight = 0
    for q in rng.uniform(lim[:, 0], lim[:, 1], size=(400, course.dof)):
        if not course.is_valid(q):
            continue
        for p in pairs:
            exact = course.pair_distance(q, p)
            if exact > 0.05:
                continue  # far apart: hulls decide there, and FCL is slow
            bound = course.pair_distance(q, p, kind="parts")
            assert bound <= exact + 1e-12, (course.pair_names[p], bound, exact)
            near += 1
            tight += bound >= 0.9 * exact
    # not vacuous: pairs within 5 cm, most bounds within 10% of the distance
    assert near > 40 and tight > 0.9 * near


def test_near_the_base_hollow_the_parts_prove_what_the_hulls_cannot(course):
    # the claw over the base's hollow (issue 30's edge 23e1, its end): the hulls touch
    # while the meshes are centimetres apart; the parts' bound is the distance
    q = np.array([-1.263, -0.473, -0.852, -1.474])
    p = course.pair_names.index(("base_link", "claw_support"))
    exact = course.pair_distance(q, p)
    assert exact > 0.01 and course.pair_distance(q, p, kind="hulls") <= 0.0
    bound = course.pair_distance(q, p, kind="parts")
    assert 0.95 * exact <= bound <= exact + 1e-12
    d, was_exact = Ladder(course, clear=0.0).state_bound(q, p, above=0.001)
    assert not was_exact and d == bound


def test_parts_are_cached_by_content_and_a_convex_mesh_keeps_its_hull(course):
    mesh = _mesh(course, "claw_support")
    cache = _Cache()
    hull = mesh_hull(np.asarray(mesh.vertices, float))
    first = mesh_parts(mesh.vertices, mesh.faces, hull, cache)
    assert len(cache.data) == 1 and first.count > 1
    again = mesh_parts(mesh.vertices, mesh.faces, hull, cache)
    for k, a in first.arrays().items():
        assert np.array_equal(a, getattr(again, k)), k
    # the same bound from either
    tb = np.eye(4)
    tb[:3, 3] = (0.0, 0.0, 0.6)
    bounds = [PartBounds([partial(lambda p: p, parts)] * 2).bound(0, np.eye(4), 1, tb)
              for parts in (first, again)]
    assert bounds[0] == bounds[1]
    # a sphere: its hull strays microns from it, one part, the hull itself
    ball = trimesh.creation.icosphere(3, radius=0.05)
    one = mesh_parts(ball.vertices, ball.faces, mesh_hull(np.asarray(ball.vertices)), cache)
    assert one.count == 1 and len(one.vertices) == len(mesh_hull(ball.vertices).vertices)


@pytest.mark.parametrize("seed", range(3))
def test_two_convex_parts_get_their_distance(seed):
    # GJK only steers the direction: for convex bodies the bound is the distance
    rng = np.random.default_rng(seed)
    box = trimesh.creation.box(extents=(0.1, 0.04, 0.07))
    ta, tb = np.eye(4), np.eye(4)
    ta[:3, :3] = trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3]
    tb[:3, 3] = (0.3, 0.0, 0.0) + rng.normal(size=3) * 0.05
    one = np.array([-1])
    pb = PartBounds([lambda: Parts.of([(np.asarray(box.vertices), 0.0)], one, one),
                     lambda: Parts.of([(np.zeros((1, 3)), 0.05)], one, one)])
    # the box's distance to the ball's centre, by dense sampling of its surface
    placed = box.copy()
    placed.apply_transform(ta)
    centre = tb[:3, 3]
    _, dist, _ = trimesh.proximity.closest_point(placed, centre[None])
    assert pb.bound(0, ta, 1, tb) == pytest.approx(dist[0] - 0.05, abs=1e-7)
    n = np.array([1.0, 0.0, 0.0])
    assert gjk_direction(np.asarray(box.vertices), ta, np.zeros((1, 3)), tb, n)
    assert abs(np.linalg.norm(n) - 1.0) < 1e-12


def test_a_tree_must_match_its_parts():
    with pytest.raises(ValueError, match="2 parts for a tree of 1 leaves"):
        Parts.of([(np.zeros((1, 3)), 0.0)] * 2, np.array([-1]), np.array([-1]))


# -- the builder's shortcuts give what the plain numpy gives ----------------------------------

def test_unique_rows_is_numpys_unique_by_rows():
    from arduinobot.planner.collision.bounds.parts import _unique_rows

    rng = np.random.default_rng(5)
    pts = rng.integers(-3, 4, size=(2000, 3)).astype(float) / 7  # many repeats
    pts[::97] = -0.0  # signed zeros compare equal
    rows, inverse = _unique_rows(pts)
    want, want_inverse = np.unique(pts, axis=0, return_inverse=True)
    assert np.array_equal(rows, want) and np.array_equal(inverse, want_inverse.ravel())
    assert np.array_equal(rows[inverse], pts)


def test_largest_is_the_head_of_a_stable_argsort():
    from arduinobot.planner.collision.bounds.parts import _largest

    rng = np.random.default_rng(6)
    for n in (5, 32, 33, 500):
        x = rng.integers(0, 9, size=n).astype(float)  # ties at the cut
        assert np.array_equal(_largest(x, 32), np.argsort(-x, kind="stable")[:32])


def test_gap_stops_early_at_the_same_farthest_point():
    from arduinobot.planner.collision.bounds.parts import _gap, _point_triangle

    rng = np.random.default_rng(7)
    tri = rng.uniform(-1, 1, size=(300, 3, 3))
    pts = rng.uniform(-2, 2, size=(40, 3))
    brute = max(min(_point_triangle(p, t) for t in tri) for p in pts)
    assert _gap(pts, tri) == np.sqrt(brute)
