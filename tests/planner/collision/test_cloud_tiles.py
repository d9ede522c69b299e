"""A cloud's boundary in tiles (arduinobot.planner.collision.cloud_tiles): the same
distances and contacts as the cell boxes themselves, with only the tiles near a query
built."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from arduinobot.planner.collision import cloud_tiles
from arduinobot.planner.collision.cloud_body import exposed_faces
from arduinobot.planner.collision.cloud_tiles import CloudSurface
from arduinobot.scene.cloud import Cells


def _box_distance(points: np.ndarray, cells: Cells) -> np.ndarray:
    # distance of each point to the nearest cell box, by numpy (no FCL)
    lo = cells.index * cells.resolution
    hi = lo + cells.resolution
    gap = np.maximum(np.maximum(lo[None] - points[:, None], points[:, None] - hi[None]), 0)
    return np.linalg.norm(gap, axis=2).min(axis=1)


@pytest.fixture
def blob(monkeypatch) -> Cells:
    monkeypatch.setattr(cloud_tiles, "TILE", 4)  # 3 x 3 x 3 tiles of a 10-cell blob
    rng = np.random.default_rng(11)
    idx = np.unique(rng.integers(0, 10, (500, 3)), axis=0)
    return Cells(idx, 0.02)


def _sphere(center: np.ndarray, r: float) -> tuple:
    # an FCL sphere and its box (centre, axes as columns, half sizes), turned 30 degrees
    # about z as a link's box may be
    c, s = np.cos(0.5), np.sin(0.5)
    axes = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return (fcl.CollisionObject(fcl.Sphere(r), fcl.Transform(np.eye(3), center)),
            center, axes, np.full(3, r))


def test_the_tiles_hold_exactly_the_unions_boundary(blob):
    s = CloudSurface(blob)
    assert len(s) == 27 and s.built == 0
    total = sum(len(exposed_faces(blob, m)[1]) for m in s._members)
    members = np.sort(np.concatenate(s._members))
    np.testing.assert_array_equal(members, np.arange(len(blob)))  # each cell in one tile
    # the tiles' faces are the whole boundary's, runs cut at the tiles' edges only
    assert total >= len(exposed_faces(blob)[1])
    lo, hi = blob.index.min(axis=0) * 0.02, (blob.index.max(axis=0) + 1) * 0.02
    assert np.allclose(s.lo.min(axis=0), lo) and np.allclose(s.hi.max(axis=0), hi)


def test_distances_are_the_boxes_and_only_near_tiles_are_built(blob):
    s = CloudSurface(blob)
    rng = np.random.default_rng(12)
    pts = rng.uniform(-0.08, 0.28, (300, 3))
    expect = _box_distance(pts, blob)
    outside = expect > 1e-4
    assert outside.sum() > 50
    got = []
    for p in pts[outside]:
        got.append(s.distance(*_sphere(p, 1e-9)))
    np.testing.assert_allclose(got, expect[outside], atol=1e-6)
    fresh = CloudSurface(blob)
    d = fresh.distance(*_sphere(np.array([-0.05, -0.05, -0.05]), 1e-9))
    assert d == pytest.approx(_box_distance(np.array([[-0.05] * 3]), blob)[0], abs=1e-6)
    assert 1 <= fresh.built < len(fresh)  # a corner's query: the tiles there, not all


def test_contacts_are_the_boxes(blob):
    s = CloudSurface(blob)
    rng = np.random.default_rng(13)
    r = 0.006
    centers = rng.uniform(-0.03, 0.23, (300, 3))
    d = _box_distance(centers, blob)
    # clearly apart or clearly touching, and not wholly inside the union (its surface
    # is what is measured, as for a mesh obstacle)
    for c, dist in zip(centers, d):
        if abs(dist - r) < 1e-4 or dist == 0:
            continue
        assert s.collide(*_sphere(c, r)) == (dist < r), (c, dist)
        assert s.within(*_sphere(c, 1e-9), r) == (dist < r), (c, dist)


def test_a_long_cloud_in_real_tiles():
    # a 3 m row of cells: tiles of TILE cells along it
    n = 300
    cells = Cells(np.column_stack([np.arange(n), np.zeros(n, int), np.zeros(n, int)]), 0.01)
    s = CloudSurface(cells)
    assert len(s) == -(-n // cloud_tiles.TILE)
    assert s.distance(*_sphere(np.array([2.955, 0.005, 0.2]), 0.01)) == \
        pytest.approx(0.2 - 0.01 - 0.01, abs=1e-6)
    assert s.built <= 2
