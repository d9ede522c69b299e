"""The order the certifier's walk takes the pairs in: nearest first.

The walk proves each pair along the whole motion in turn, and a step never needs to prove
a pair closer than the smallest clearance certified so far (any pair's: the motion's
certified clearance is that minimum either way). Walked first, the pairs that come
nearest set that minimum early, and every pair walked after them steps by ``(d - low) /
speed`` instead of ``d / 2 / speed``: longer steps, fewer tree bounds, the same proof
(soundness never depends on the order: each step covers down to at least the
clearance). The pairs' nearness is read from their OBB-tree bounds at the motion's
piece starts and its end (a bound per pair and state, capped: a far pair costs one box
test).
"""

from __future__ import annotations

import numba
import numpy as np

from arduinobot.planner.collision.bounds.obbtree import Forest
from arduinobot.planner.collision.proof.advance import Work, tree_lower_bound
from arduinobot.planner.collision.table import Bodies, Pairs, place_carried
from arduinobot.planner.kinematics.chain import Chain, _fk_into

# [m] a pair farther than this at every state the order reads is as far as any (one box
# test at the root for most of them): the walk's own cap on what a tree bound proves
CAP = 0.03


@numba.njit(cache=True, nogil=True)
def nearest_bounds(states: np.ndarray, chain: Chain, bodies: Bodies, pairs: Pairs,
                   forest: Forest, work: Work, out: np.ndarray) -> None:
    """``out[p]`` (n_pairs,) gets pair ``p``'s smallest OBB-tree lower bound [m] over
    ``states`` (m, dof), at most :data:`CAP`; a pair no joint moves (all weights 0: the
    walk passes over it) gets ``inf``."""
    index, weight, _ = pairs
    poses, stack, gaps = work
    frame, link, pose, carried = bodies.frame, bodies.link, bodies.pose, bodies.carried
    center, axes, half, left, right, root = forest
    parent, origin, jtype, axis, src, scale, offset = chain
    scratch = np.empty((8, 3, 3))
    npair = index.shape[0]
    moving = np.zeros(npair, np.bool_)
    for p in range(npair):
        out[p] = np.inf
        for j in range(weight.shape[1]):
            if weight[p, j] > 0.0:
                moving[p] = True
                break
        if moving[p]:
            out[p] = CAP
    for i in range(states.shape[0]):
        _fk_into(states[i], parent, origin, jtype, axis, src, scale, offset, poses)
        place_carried(frame, link, pose, carried, poses)
        for p in range(npair):
            if not moving[p]:
                continue
            a, b = index[p, 0], index[p, 1]
            ta = poses[frame[a]] if frame[a] >= 0 else pose[a]
            tb = poses[frame[b]] if frame[b] >= 0 else pose[b]
            d = tree_lower_bound(ta, root[a], tb, root[b], center, axes, half, left, right,
                                 0.0, CAP, stack, gaps, scratch)
            if d < out[p]:
                out[p] = d


def walk_order(states: np.ndarray, chain: Chain, bodies: Bodies, pairs: Pairs,
               forest: Forest, work: Work) -> np.ndarray:
    """The pairs' indices (int64) nearest first by :func:`nearest_bounds` over ``states``
    (m, dof) (ties, and pairs the walk passes over, in index order)."""
    near = np.empty(pairs.index.shape[0])
    nearest_bounds(np.ascontiguousarray(states, float), chain, bodies, pairs, forest, work,
                   near)
    return np.argsort(near, kind="stable").astype(np.int64)
