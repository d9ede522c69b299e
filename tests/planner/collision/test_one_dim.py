"""One-dimensional pairs proven by cached cells (src/arduinobot/planner/collision/proof/certify.py): the two
fingers along the mimic, a link turning past an obstacle about one axis. Their bound is
never above the pair's true distance anywhere on the motion, the verdicts are the walk's,
and the cells are kept with the world."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.obstacles import Obstacle


@pytest.fixture(scope="module")
def world(course_ws):
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})
    return CollisionWorld(d, obstacles=[Obstacle("p1", "cylinder", radius=0.05, length=1.0,
                                                 xyz=(0.55, 0.0, 0.5))])


def _pieces(path: np.ndarray) -> tuple[np.ndarray, ...]:
    d = np.diff(path, axis=0)
    L = np.linalg.norm(d, axis=1)
    u = d / L[:, None]
    return path[:-1], u, u, L


def _motions(w: CollisionWorld, n: int, *, free: bool = True) -> list[np.ndarray]:
    # seeded two-state motions of arm and gripper together, free (or colliding between
    # free ends)
    lim = w.description.robot.position_limits(w.kin.joint_names)
    rng = np.random.default_rng(3)
    out: list[np.ndarray] = []
    while len(out) < n:
        a, b = rng.uniform(lim[:, 0], lim[:, 1]), rng.uniform(lim[:, 0], lim[:, 1])
        if not (w.is_valid(a) and w.is_valid(b)):
            continue
        if (w.first_invalid(interpolate(np.array([a, b]), 0.002)) < 0) == free:
            out.append(np.array([a, b]))
    return out


def test_the_fingers_are_one_dimensional(world):
    c = Certifier(world, fraction=0.5)
    fresh = Certifier(CollisionWorld(world.description, obstacles=world.obstacles))
    fingers = world.pair_names.index(("gripper_right", "gripper_left"))
    # proven by cells from the first motion on, no walk needed first
    assert fingers in fresh.one_dim.proven(*_pieces(_motions(world, 1)[0]))
    names = {world.pair_names[p]: j for p, j in c.one_dim.pairs.items()}
    assert names[("gripper_right", "gripper_left")] == 3  # joint_4 and its mimic
    # a pair two joints move is not; nor one with an obstacle (a scene's, not the robot's)
    assert ("base_link", "horizontal_arm") not in names
    assert ("base_plate", "p1") not in names


def test_cell_bounds_never_exceed_the_distance_on_the_motion(world):
    c = Certifier(world, fraction=0.5)
    proven = 0
    for path in _motions(world, 6):
        d = np.diff(path, axis=0)
        L = np.linalg.norm(d, axis=1)
        u = d / L[:, None]
        got = c.one_dim.proven(path[:-1], u, u, L)
        qs = interpolate(path, 0.01)
        for p, bound in got.items():
            assert bound > world.padding
            true = min(world.pair_distance(q, p) for q in qs)
            assert bound <= true + 1e-9, (world.pair_names[p], bound, true)
            proven += 1
    assert proven >= 6  # the fingers at least, on every motion


def test_same_verdicts_as_the_walk_and_cells_kept_with_the_world(world):
    on, off = Certifier(world, fraction=0.5), Certifier(world, fraction=0.5)
    off.one_dim.pairs = {}  # the walk alone
    motions = _motions(world, 4)
    hits = _motions(world, 4, free=False)
    # the proof alone decides (no samples first): a colliding motion is refused by the
    # walk where its pair comes close, cells or not
    for path, free in [(m, True) for m in motions] + [(m, False) for m in hits]:
        a, b = on.path(path, sample_step=None), off.path(path, sample_step=None)
        assert a.free == b.free == free
    n = len(world.bodies.proofs["one_dim"].cells)
    assert n > 0
    Certifier(world, fraction=0.5).path(motions[0])  # a new certifier: no new cell
    assert len(world.bodies.proofs["one_dim"].cells) == n


def test_a_gripper_closing_to_its_limit_is_proven_by_cells(world):
    # the closed fingers' hulls touch (6 mm apart): cells there take the trees' bound,
    # and a motion ending on the limit needs no cell beyond it (the fingers overlap there)
    c = Certifier(world, fraction=0.5)
    fingers = world.pair_names.index(("gripper_right", "gripper_left"))
    lim = world.description.robot.position_limits(world.kin.joint_names)
    assert lim[3, 1] == 0.0  # (the course's gripper closes at 0)
    path = np.array([[0.3, 0.2, -0.1, -0.5], [0.3, 0.2, -0.1, 0.0]])
    got = c.one_dim.proven(*_pieces(path))
    assert fingers in got
    true = min(world.pair_distance(q, fingers) for q in interpolate(path, 0.005))
    assert world.padding < got[fingers] <= true
    # where the hulls touch, exact distances chained from the open side prove most of
    # the true gap (the trees' bound there: tens of microns)
    assert got[fingers] > 0.5 * true


def test_motions_a_hair_past_the_limits_grow_the_row_on_either_side(world):
    # (blends and rounding can take a joint a hair past its limit): the row of cells
    # grows to hold them, below and then above, keeping what was proven
    c = Certifier(world, fraction=0.5)
    fingers = world.pair_names.index(("gripper_right", "gripper_left"))
    lo, hi = world.description.robot.position_limits(world.kin.joint_names)[3]
    below = np.array([[0.3, 0.2, -0.1, lo - 0.015], [0.3, 0.2, -0.1, lo + 0.3]])
    above = np.array([[0.3, 0.2, -0.1, -0.4], [0.3, 0.2, -0.1, hi + 1e-9]])
    first = c.one_dim.proven(*_pieces(below))[fingers]
    c.one_dim.proven(*_pieces(above))  # (no cell proves past the closed limit)
    assert c.one_dim.proven(*_pieces(below))[fingers] == first


class _Kept:
    """An artifact cache in memory, counting what is stored and read by kind."""

    def __init__(self) -> None:
        self.items: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        self.stored: dict[str, int] = {}
        self.read: dict[str, int] = {}

    def load(self, kind: str, key: str) -> dict[str, np.ndarray] | None:
        got = self.items.get((kind, key))
        if got is not None:
            self.read[kind] = self.read.get(kind, 0) + 1
        return got

    def store(self, kind: str, key: str, arrays: dict[str, np.ndarray]) -> None:
        self.stored[kind] = self.stored.get(kind, 0) + 1
        self.items[(kind, key)] = {k: np.array(v) for k, v in arrays.items()}


def test_rows_are_kept_in_the_artifact_cache_by_content(world):
    # with a cache, a pair's whole row is proven at its first motion and kept by
    # content: a world built later (a fresh worker) reads it and proves no cell; another
    # clearance is another key
    kept = _Kept()
    d, obstacles = world.description, world.obstacles
    motion = _pieces(_motions(world, 1)[0])
    first = Certifier(CollisionWorld(d, obstacles=obstacles, cache=kept))
    proven = first.one_dim.proven(*motion)
    assert proven and kept.stored["one-dim-cells"] == len(first.one_dim.pairs)
    rows = {k: v[1] for k, v in first.one_dim._rows.items()}
    assert all(not np.isnan(r).any() for r in rows.values())  # whole, not as read

    later = Certifier(CollisionWorld(d, obstacles=obstacles, cache=kept))

    def no_cell(*args):
        raise AssertionError("a cell was proven again")

    later.one_dim._cell = no_cell  # type: ignore[method-assign]
    assert later.one_dim.proven(*motion) == proven
    assert kept.read["one-dim-cells"] == len(first.one_dim.pairs)
    for k, r in later.one_dim._rows.items():
        assert np.array_equal(r[1], rows[k])
    # a world without a cache proves the same pairs, cell by cell as motions read them
    # (here by no more: the whole rows chained every weak cell)
    lazy = Certifier(CollisionWorld(d, obstacles=obstacles)).one_dim.proven(*motion)
    assert lazy.keys() == proven.keys()
    assert all(proven[p] >= lazy[p] - 1e-12 for p in proven)

    padded = Certifier(CollisionWorld(d, obstacles=obstacles, padding=0.001, cache=kept))
    padded.one_dim.proven(*motion)
    assert kept.stored["one-dim-cells"] == 2 * len(first.one_dim.pairs)
