"""src/arduinobot/planner/planning/pathfinding/shortcut.py: simplification keeps every edge free by the caller's
judge, never lengthens the path, keeps its ends, and is seeded."""

from __future__ import annotations

import numpy as np

from arduinobot.planner.planning.pathfinding.shortcut import reduce_vertices, shortcut_path


def _wall(a: np.ndarray, b: np.ndarray) -> bool:
    """A wall on x = 0.5 for y < 0.8: an edge is free unless it crosses it there (sampled
    finely: this judge is the test's own)."""
    t = np.linspace(0.0, 1.0, 401)[:, None]
    pts = a + t * (b - a)
    side = np.sign(pts[:, 0] - 0.5)
    crossing = np.flatnonzero(np.diff(side) != 0)
    return not any(pts[i, 1] < 0.8 for i in crossing)


def _length(p: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def test_reduce_drops_what_a_free_edge_skips_and_keeps_what_the_wall_needs():
    straight = np.array([[0.0, 0.0], [0.2, 0.0], [0.4, 0.0], [0.45, 0.0]])
    assert reduce_vertices(straight, _wall).tolist() == [[0.0, 0.0], [0.45, 0.0]]
    around = np.array([[0.0, 0.0], [0.2, 0.5], [0.3, 1.0], [0.7, 1.0], [0.8, 0.5],
                       [1.0, 0.0]])
    out = reduce_vertices(around, _wall)
    assert 2 < len(out) < len(around)  # some dropped, not the ones the wall needs
    assert all(_wall(a, b) for a, b in zip(out[:-1], out[1:]))
    assert (out[0] == around[0]).all() and (out[-1] == around[-1]).all()


def test_shortcuts_keep_edges_free_shorten_and_repeat_with_their_seed():
    rng = np.random.default_rng(11)
    tried = 0
    for _ in range(20):
        mid = [[rng.uniform(0.0, 1.0), rng.uniform(0.85, 1.5)] for _ in range(6)]
        path = np.array([[0.0, 0.0], *sorted(mid), [1.0, 0.0]])
        if not all(_wall(a, b) for a, b in zip(path[:-1], path[1:])):
            continue  # the test needs a free path to start from
        out = shortcut_path(path, _wall, seed=3)
        assert all(_wall(a, b) for a, b in zip(out[:-1], out[1:]))
        assert _length(out) <= _length(path) + 1e-12
        assert (out[0] == path[0]).all() and (out[-1] == path[-1]).all()
        assert np.array_equal(out, shortcut_path(path, _wall, seed=3))
        tried += 1
    assert tried >= 10


def test_an_edge_known_blocked_is_never_asked_again():
    around = np.array([[0.0, 0.0], [0.3, 1.0], [0.7, 1.0], [1.0, 0.0]])
    asked: list[tuple[float, ...]] = []

    def judge(a: np.ndarray, b: np.ndarray) -> bool:
        asked.append((*a, *b))
        return _wall(a, b)

    out = shortcut_path(around, judge, seed=3, blocked=[(around[0], around[-1])])
    assert (0.0, 0.0, 1.0, 0.0) not in asked and asked  # the others still judged
    assert all(_wall(a, b) for a, b in zip(out[:-1], out[1:]))
    asked.clear()
    again = shortcut_path(around, judge, seed=3)
    assert (0.0, 0.0, 1.0, 0.0) in asked  # without it, asked first
    assert np.array_equal(out, again)  # same verdicts, same path
