"""The proof's cost: its pairs walked nearest first (:mod:`.nearness`), its whole cost
bounded (``max_bounds``: tree bounds, walk stops and exact queries), and neither making
a certificate less sound: every certified motion is free at 0.002 rad (FCL), a near
contact is certified or refused, never certified in contact."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.certify import EXACT_COST, STOP_COST, Certifier
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.proof.nearness import CAP, nearest_bounds, walk_order
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.obstacles import Obstacle
from tests.planner.collision.test_certify import needle  # noqa: F401 (a fixture)


@pytest.fixture(scope="module")
def cluttered():
    d = load_description()
    obs = (Obstacle("table", "box", size=(0.6, 1.2, 0.05), xyz=(0, 1.0, 0.6)),
           Obstacle("post", "cylinder", radius=0.05, length=1.0, xyz=(0.6, -0.5, 0.5)),
           Obstacle("ball", "sphere", radius=0.1, xyz=(-0.6, 0.6, 1.2)))
    return CollisionWorld(d, obstacles=obs)


def _free_states(world, rng, n):
    lim = world.description.robot.position_limits(world.kin.joint_names)
    out = []
    for _ in range(100 * n):  # (about 3 in 5 are free)
        if len(out) == n:
            break
        q = rng.uniform(lim[:, 0], lim[:, 1])
        if world.check(q).valid:
            out.append(q)
    assert len(out) == n
    return np.array(out)


def test_the_order_bounds_never_exceed_the_exact_distance(cluttered):
    w = cluttered
    rng = np.random.default_rng(11)
    states = _free_states(w, rng, 12)
    cert = Certifier(w, fraction=0.5)
    pairs = w.table.pairs
    near = np.empty(len(pairs.index))
    moving = pairs.weight.max(axis=1) > 0
    for k in range(0, len(states), 3):
        nearest_bounds(states[k:k + 3], w.chain, w.table.bodies, pairs, w.forest,
                       cert._work, near)
        assert np.all(near[~moving] == np.inf)
        for p in np.flatnonzero(moving):
            exact = min(w.pair_distance(q, int(p)) for q in states[k:k + 3])
            assert near[p] <= min(exact, CAP) + 1e-9, w.pair_names[p]
    # nearest first: the order is the bounds' (a check that it is not index order here)
    order = walk_order(states[:3], w.chain, w.table.bodies, pairs, w.forest, cert._work)
    nearest_bounds(states[:3], w.chain, w.table.bodies, pairs, w.forest, cert._work, near)
    assert np.all(np.diff(near[order]) >= 0)
    assert sorted(order) == list(range(len(order)))
    assert not np.array_equal(order, np.arange(len(order)))


def test_paths_certified_nearest_first_are_free_at_every_0002_rad_sample(cluttered):
    w = cluttered
    rng = np.random.default_rng(23)
    nearest, indexed = Certifier(w, fraction=0.5), Certifier(w, fraction=0.5)
    indexed._order = lambda motion, pairs: np.arange(len(pairs.index), dtype=np.int64)
    free = refused = 0
    for _ in range(25):
        path = _free_states(w, rng, 3)
        path[1:] = path[0] + 0.4 * (path[1:] - path[0])  # short enough to pass at times
        if w.first_invalid(interpolate(path, 0.01)) >= 0:
            continue
        cert = nearest.path(path, sample_step=None)
        # the order changes the steps, never the verdict
        assert indexed.path(path, sample_step=None).free == cert.free
        dense = interpolate(path, 0.002)
        if cert.free:
            free += 1
            assert w.first_invalid(dense) == -1
            idx = np.linspace(0, len(dense) - 1, 9).astype(int)
            assert cert.certified_clearance <= w.min_clearance(dense[idx])[0] + 1e-9
        else:
            refused += 1
    assert free >= 5  # the test exercised certification


@pytest.mark.parametrize("max_bounds", [20, 200, 2000, 500_000])
def test_a_near_contact_edge_is_certified_or_refused_never_certified_in_contact(
        needle, max_bounds):  # noqa: F811 (the fixture)
    # the plate is at 0.101 rad: at 0.1 rad the needle passes ~0.4 mm from it
    near_miss = np.array([[0.0], [0.1]])
    gap = needle.check(np.array([0.1]), clearance=True).clearance
    assert 0.0002 < gap < 0.0006
    cert = Certifier(needle, fraction=0.5, max_bounds=max_bounds).path(near_miss,
                                                                       sample_step=None)
    if cert.free:
        assert needle.first_invalid(interpolate(near_miss, 0.002)) == -1
        assert cert.certified_clearance <= gap
    else:
        assert np.isnan(cert.failure[3])  # only a spent budget refuses a free motion
    # crossing the plate is refused under every budget
    for path in ([[0.0], [0.102]], [[0.0], [0.2]]):
        crossing = Certifier(needle, fraction=0.5, max_bounds=max_bounds).path(
            np.array(path), sample_step=None)
        assert not crossing.free
    if max_bounds == 500_000:
        assert cert.free  # the default budget proves the near miss


def test_the_budget_counts_the_ladder_s_queries_and_bounds_the_whole_proof(cluttered):
    w = cluttered
    rng = np.random.default_rng(5)
    probe = Certifier(w, fraction=0.5)
    # a path whose proof stops the walk (hull queries near the obstacles)
    for _ in range(200):
        path = _free_states(w, rng, 2)
        path[1] = path[0] + 0.5 * (path[1] - path[0])
        if w.first_invalid(interpolate(path, 0.01)) >= 0:
            continue
        cert = probe.path(path, sample_step=None)
        stops = cert.rungs.hulls
        if cert.free and stops >= 2:
            break
    else:
        pytest.fail("no seeded path stopped the walk twice")
    cost = cert.bounds + STOP_COST * stops + EXACT_COST * cert.exact
    assert Certifier(w, fraction=0.5, max_bounds=cost).path(path, sample_step=None).free
    # the bounds alone, without the stops' cost, do not pay for it
    short = Certifier(w, fraction=0.5, max_bounds=cert.bounds).path(path, sample_step=None)
    assert not short.free and np.isnan(short.failure[3])
    # and a budget below a tenth of the bounds is spent within it
    tight = Certifier(w, fraction=0.5, max_bounds=cert.bounds // 10).path(
        path, sample_step=None)
    assert not tight.free and tight.bounds <= cert.bounds // 10 + 1
