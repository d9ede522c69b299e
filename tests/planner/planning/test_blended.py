"""arduinobot.planner.planning.pathfinding.blended: a path's blends proven with it in one walk."""

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pathfinding.blended import prove_blended
from arduinobot.planner.planning.pathfinding.paths import PathPlanner, PathRequest
from arduinobot.planner.timing.curve import build_curve
from arduinobot.scene.obstacles import Obstacle

PILLAR = Obstacle("pillar", "box", size=(0.15, 0.15, 3.0), xyz=(0.0, 0.9, 0.6))
START = np.array([1.2, -0.6, -0.6, 0.0])
GOAL = np.array([-1.2, -0.6, -0.6, 0.0])


@pytest.fixture(scope="module")
def env():
    d = load_description()
    w = CollisionWorld(d, obstacles=[PILLAR])
    pp = PathPlanner(w, d)
    # one plan first, with a long budget: kernels compiled into a cold cache inside the
    # timed search can spend its budget (the search with room, or all of it), and the
    # same seed then gives another path, or none
    pp.solve(PathRequest(start=START, goal=_goal(w), seed=0, planning_time=120.0),
             blend=True)
    return w, pp


def _goal(w):
    return JointGoal(dict(zip(w.kin.joint_names[:3], GOAL[:3])))


def _dense(curve, step=0.002):
    return np.concatenate([s.dense(step) for s in curve.sections])


@pytest.mark.parametrize("seed", [3, 7, 11])
def test_blended_curve_is_the_one_separate_proofs_build(env, seed):
    w, pp = env
    goal = _goal(w)
    res = pp.solve(PathRequest(start=START, goal=goal, seed=seed), blend=True)
    assert not res.straight_line and len(res.path) >= 3
    assert res.curve is not None and res.certificate is not None and res.certificate.free
    # the same curve as blending each corner with its own proof (none shrunk)
    separate = build_curve(res.path, pp.proof)
    assert [c.kind for c in separate.corners] == [c.kind for c in res.curve.corners]
    assert [c.radius for c in separate.corners] == [c.radius for c in res.curve.corners]
    assert all(c.shrinks == 0 for c in separate.corners)
    for a, b in zip(separate.sections, res.curve.sections):
        assert np.array_equal(a.starts, b.starts) and np.array_equal(a.lengths, b.lengths)
    # and free where an independent dense check looks
    assert w.first_invalid(_dense(res.curve)) == -1
    # the plain solve returns the same path, without a curve
    plain = pp.solve(PathRequest(start=START, goal=goal, seed=seed))
    assert np.array_equal(plain.path, res.path) and plain.curve is None


def test_a_grazing_edge_is_refused_with_its_blends(env):
    w, pp = env
    # an edge straight through the pillar (its samples are not checked first here)
    bad = np.array([START, [0.0, -0.6, -0.6, 0.0], [0.0, 0.3, 0.3, 0.0]])
    assert w.first_invalid(interpolate(bad, 0.01)) >= 0
    cert, curve = prove_blended(pp.proof, bad, w)
    assert not cert.free and curve is None


def test_an_edge_refused_in_a_request_is_not_taken_again(env):
    # what a re-plan after a failed proof is given: the failed edge, refused unchecked
    # (the same seed would draw an escape edge, or a shortcut, exactly as before)
    w, pp = env
    goal = _goal(w)
    req = PathRequest(start=START, goal=goal, seed=7)
    first = pp.solve(req)
    a, b = first.path[0], first.path[1]
    again = pp._solve(req, blend=False, refused=frozenset({(a.tobytes(), b.tobytes())}))
    assert not np.array_equal(again.path[1], b)
    assert again.certificate is not None and again.certificate.free
    assert w.first_invalid(interpolate(again.path, 0.002)) == -1
    # and the next request starts with nothing refused
    assert np.array_equal(pp.solve(req).path, first.path)
