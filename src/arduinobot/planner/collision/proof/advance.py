"""Conservative advancement: proving a pair free over a stretch of states, not sampling it.

Two ingredients, both exact bounds:

- a lower bound on the distance between two bodies at one state, from their OBB trees
  (branch and bound over node pairs; a box pair's bound is the largest gap along the 15
  separating axes, or between the boxes' bounding spheres);
- a bound on how far any point of one body can move relative to the other per radian of
  each joint, ``weight[pair, joint]`` [m/rad]: the largest distance from the joint's axis
  to the body, summed over the joints between the two bodies (joints both hang from
  move them together and cancel).

So a pair at distance >= ``d`` at state ``q`` stays apart at ``q'`` while
``d - sum_j weight_j |q'_j - q_j| > padding``: every state of the sequence in that stretch
is proven free for that pair and skipped. Only pairs that come close get the tree
descent at every state, and only pairs whose leaf boxes touch reach FCL. The result is
the same as checking every state (the bound is a proof), typically for a tenth of the work.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numba
import numpy as np

from arduinobot.description.model import Joint, Robot
from arduinobot.planner.collision.bounds.obbtree import (
    Forest,
    box_in_frame,
    in_box_frame,
    relative_pose,
)
from arduinobot.planner.collision.proof.body_speed import local_rates
from arduinobot.planner.collision.table import Bodies, Pairs, place_carried
from arduinobot.planner.kinematics.chain import Chain, _fk_into

# [m] a pair needs this much more than the padding to be called free by a bound:
# absorbs rounding in poses, boxes and weights, far below any mesh feature
MARGIN = 1e-6


class Work(NamedTuple):
    """Work buffers of the walks (reused, so a call allocates nothing large).

    Attributes:
        poses: link poses, shape (n_links, 4, 4).
        stack: tree descent pairs, shape (s, 2) int64.
        gaps: their inherited bounds, shape (s,).
    """

    poses: np.ndarray
    stack: np.ndarray
    gaps: np.ndarray

    @classmethod
    def of(cls, n_links: int, depth: int = 4096) -> Work:
        return cls(np.empty((n_links, 4, 4)), np.empty((depth, 2), np.int64), np.empty(depth))


class SweepCarry(NamedTuple):
    """What :func:`sweep` carries per pair between its resumed calls.

    Attributes:
        budget: the distance [m] proven at state ``since`` (-1: none yet; 0: marked),
            shape (n_pairs,).
        since: that state, shape (n_pairs,) int64.
        rates: the :func:`~.body_speed.local_rates` (rate, turn) there of the pair's
            body that moves by a static one, shape (n_pairs, 2, dof).
    """

    budget: np.ndarray
    since: np.ndarray
    rates: np.ndarray

    @classmethod
    def of(cls, n_pairs: int, dof: int) -> SweepCarry:
        return cls(np.empty(n_pairs), np.zeros(n_pairs, np.int64), np.empty((n_pairs, 2, dof)))


def _rigid(joints: tuple[Joint, ...]) -> np.ndarray:
    t = np.eye(4)
    for j in joints:
        t = t @ j.origin.matrix()
    return t


def _axis(j: Joint) -> np.ndarray:
    a = np.asarray(j.axis, float)
    return a / (np.linalg.norm(a) or 1.0)


def joint_reach(robot: Robot, link: str, points: np.ndarray) -> dict[str, float]:
    """For each movable joint above ``link``: a bound [m/rad] (prismatic: [m/m]) on how far
    any of ``points`` (shape (v, 3), link frame [m]) moves per unit of that joint, in
    every configuration: the largest distance from the joint's axis to the points."""
    chain = robot.link_path(link)
    out: dict[str, float] = {}
    rho = 0.0  # bound on |point - origin of the next movable joint below|, any config
    nxt = None  # index of that joint
    for i in range(len(chain) - 1, -1, -1):
        j = chain[i]
        if not j.movable:
            continue
        u = _axis(j)
        if nxt is None:  # rigid below: exact over the points
            p = (_rigid(chain[i + 1:])[:3, :3] @ points.T).T + _rigid(chain[i + 1:])[:3, 3]
            along = p @ u
            r = float(np.sqrt(np.max(np.sum(p * p, axis=1) - along ** 2).clip(0)))
            rho_i = float(np.max(np.linalg.norm(p, axis=1)))
        else:
            below = chain[nxt]
            c = _rigid(chain[i + 1:nxt + 1])[:3, 3]
            travel = 0.0
            if below.type == "prismatic" and below.limit is not None:
                travel = max(abs(below.limit.lower or 0.0), abs(below.limit.upper or 0.0))
            r = float(np.linalg.norm(c - (c @ u) * u)) + travel + rho
            rho_i = float(np.linalg.norm(c)) + travel + rho
        out[j.name] = 1.0 if j.type == "prismatic" else r
        rho, nxt = rho_i, i
    return out


def pair_weights(robot: Robot, joint_names: tuple[str, ...], bodies: list[tuple[str | None,
                 np.ndarray]], pairs: np.ndarray, *,
                 known: Sequence[Mapping[str, float]] = ()) -> np.ndarray:
    """``weight[p, k]`` [m/rad]: how far body a of pair p can move relative to body b per
    unit of actuated joint k. ``bodies``: (link name, or None for a static obstacle;
    points (v, 3) in the link frame). Mimic joints count with |multiplier|. ``known``: the
    :func:`joint_reach` of the first ``len(known)`` bodies, already computed (the robot's
    links: the same in every world of the robot, half of a new world's build on a 7-joint
    arm when computed each time)."""
    idx = {n: k for k, n in enumerate(joint_names)}
    reach: list[Mapping[str, float]] = list(known)
    chains = []
    for i, (link, pts) in enumerate(bodies):
        if i >= len(known):
            reach.append(joint_reach(robot, link, pts) if link is not None else {})
        chains.append({j.name for j in robot.link_path(link)} if link is not None else set())
    w = np.zeros((len(pairs), len(joint_names)))
    for p, (a, b) in enumerate(pairs):
        for body, other in ((a, b), (b, a)):
            for name, r in reach[body].items():
                if name in chains[other]:
                    continue  # moves both bodies rigidly: their distance does not change
                j = robot.joints[name]
                src, mult = (j.mimic.joint, abs(j.mimic.multiplier)) if j.mimic else (name, 1.0)
                if src in idx:
                    w[p, idx[src]] += mult * r
    # rounding in the geometry above must never make a bound optimistic
    return w * (1 + 1e-9) + 1e-12


@numba.njit(cache=True, nogil=True, inline="always")
def _box_gap(ra: np.ndarray, ca: np.ndarray, ha: np.ndarray, rb: np.ndarray, cb: np.ndarray,
             hb: np.ndarray, best: float, r: np.ndarray, ar: np.ndarray,
             t: np.ndarray) -> float:
    # A lower bound on the distance between two boxes: the largest gap of their
    # projections on the 15 separating axes (projection never lengthens a distance),
    # or of their bounding spheres. Returns as soon as it reaches ``best``.
    d0, d1, d2 = cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2]
    g = (np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
         - np.sqrt(ha[0] * ha[0] + ha[1] * ha[1] + ha[2] * ha[2])
         - np.sqrt(hb[0] * hb[0] + hb[1] * hb[1] + hb[2] * hb[2]))
    if g >= best:
        return g
    in_box_frame(ra, rb, d0, d1, d2, r, ar, t)
    for i in range(3):
        gi = abs(t[i]) - (ha[i] + hb[0] * ar[i, 0] + hb[1] * ar[i, 1] + hb[2] * ar[i, 2])
        if gi > g:
            g = gi
    for j in range(3):
        gj = abs(t[0] * r[0, j] + t[1] * r[1, j] + t[2] * r[2, j]) - (
            ha[0] * ar[0, j] + ha[1] * ar[1, j] + ha[2] * ar[2, j] + hb[j])
        if gj > g:
            g = gj
    if g >= best:
        return g
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            n2 = 1.0 - r[i, j] * r[i, j]
            if n2 < 1e-8:
                continue  # near-parallel axes: the face axes already cover them
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            lhs = abs(t[i2] * r[i1, j] - t[i1] * r[i2, j])
            rhs = (ha[i1] * ar[i2, j] + ha[i2] * ar[i1, j]
                   + hb[j1] * ar[i, j2] + hb[j2] * ar[i, j1])
            gc = (lhs - rhs) / np.sqrt(n2)
            if gc > g:
                g = gc
    return g


@numba.njit(cache=True, nogil=True, inline="always")
def _pair_gap(na: int, nb: int, rel_r: np.ndarray, rel_t: np.ndarray, center: np.ndarray,
              axes: np.ndarray, half: np.ndarray, best: float, scratch: np.ndarray) -> float:
    # :func:`_box_gap` of node na (a's frame) and node nb (b's, moved by rel_r, rel_t)
    rb = scratch[2]
    cb = scratch[1, 1]
    box_in_frame(rel_r, rel_t, center[nb], axes[nb], rb, cb)
    return _box_gap(axes[na], center[na], half[na], rb, cb, half[nb], best, scratch[3],
                    scratch[4], scratch[1, 2])


@numba.njit(cache=True, nogil=True)
def tree_lower_bound(ta: np.ndarray, a: int, tb: np.ndarray, b: int, center: np.ndarray,
                     axes: np.ndarray, half: np.ndarray, left: np.ndarray, right: np.ndarray,
                     pad: float, cap: float, stack: np.ndarray, gaps: np.ndarray,
                     scratch: np.ndarray) -> float:
    """A lower bound [m] on the distance between trees ``a`` (pose ``ta``) and ``b``
    (pose ``tb``) of a :class:`.obbtree.Forest`'s arrays (root nodes ``a``, ``b``; the
    caller unpacks the forest once: this runs per pair and step): the smallest leaf-pair
    bound if one is below ``cap``, else the
    smallest gap of the node pairs the search pruned (``>= cap``: a far pair proves its
    whole distance for the box tests it took). Stops early with a value <= ``pad`` once
    a leaf pair is that close.

    ``stack`` (s, 2) int64 and ``gaps`` (s,) are work buffers; ``scratch`` (8, 3, 3).
    """
    rel_r = scratch[0]
    rel_t = scratch[1, 0]
    relative_pose(ta, tb, rel_r, rel_t)
    best = cap
    found = False  # a leaf pair below the cap set ``best``
    pruned = np.inf  # the smallest gap of a pruned node pair
    # a node pair is measured when it is pushed, so of two children the nearer is
    # popped first: a close leaf pair found early lowers ``best`` and prunes the rest
    # (the same bound, for 0.6x the box tests near a cloud of 50k cells and 0.8x near
    # two boxes, measured on bench/cloud.py's scene)
    stack[0, 0] = a
    stack[0, 1] = b
    gaps[0] = _pair_gap(a, b, rel_r, rel_t, center, axes, half, best, scratch)
    top = 1
    while top > 0:
        top -= 1
        na, nb = stack[top, 0], stack[top, 1]
        g = gaps[top]
        if g >= best:
            pruned = min(pruned, g)
            continue
        la, lb = left[na], left[nb]
        if (la < 0 and lb < 0) or top + 2 > stack.shape[0]:
            # a leaf pair (or no room to descend: the node's bound holds for its leaves)
            best = g
            found = True
            if best <= pad:
                return best
            continue
        va = half[na, 0] * half[na, 1] * half[na, 2]
        vb = half[nb, 0] * half[nb, 1] * half[nb, 2]
        if lb < 0 or (la >= 0 and va >= vb):
            a1, b1, a2, b2 = la, nb, right[na], nb
        else:
            a1, b1, a2, b2 = na, lb, na, right[nb]
        # OBB children are not nested in their parent's box, but their triangles are a
        # subset of the parent's: the ancestors' gap still bounds them
        g1 = max(g, _pair_gap(a1, b1, rel_r, rel_t, center, axes, half, best, scratch))
        g2 = max(g, _pair_gap(a2, b2, rel_r, rel_t, center, axes, half, best, scratch))
        if g2 < g1:
            a1, b1, g1, a2, b2, g2 = a2, b2, g2, a1, b1, g1
        stack[top, 0], stack[top, 1], gaps[top] = a2, b2, g2
        stack[top + 1, 0], stack[top + 1, 1], gaps[top + 1] = a1, b1, g1
        top += 2
    # every pair was pruned at or above best, which only fell: what was pruned bounds it
    return best if found else pruned


@numba.njit(cache=True, nogil=True)
def sweep(qs: np.ndarray, start: int, stop_early: bool, cum: np.ndarray, carry: SweepCarry,
          chain: Chain, bodies: Bodies, pairs: Pairs, forest: Forest, pad: float,
          horizon: float, work: Work, out: np.ndarray) -> int:
    """Mark (state, pair) where a checked pair of ``pairs`` may be closer than ``pad``;
    the rest is proven.

    Walks ``qs`` (m, dof) in order from state ``start``; with ``stop_early`` returns the
    first state given a mark (call again from the next state to resume), else walks to
    the end and returns m. ``cum`` (m, dof) gets the cumulative |joint motion| when
    ``start`` is 0. ``carry`` holds each pair's proof between resumed calls: the distance
    proven at a state, and the local rates there of the pair's body that moves by a
    static one (``pairs.mover``), so the proof lasts while the motion since, by the
    pair's every-configuration ``pairs.weight`` [m/rad] or by those local rates, stays
    below it. ``horizon`` [m] caps how far ahead one bound is asked to prove (deeper
    proofs cost more tree descent); ``out`` (m, n_pairs) int8, zeroed, gets 1 where the
    narrow phase must decide.
    """
    # unpacked once: taking an array out of a tuple costs a reference count
    budget, since, rates = carry
    index, weight, mover = pairs
    poses, stack, gaps = work
    frame, link, pose, carried = bodies.frame, bodies.link, bodies.pose, bodies.carried
    center, axes, half, left, right, root = forest
    parent, origin, jtype, axis, src, scale, offset = chain
    m, dof = qs.shape
    npair = index.shape[0]
    if start == 0:
        for j in range(dof):
            cum[0, j] = 0.0
        for i in range(1, m):
            for j in range(dof):
                cum[i, j] = cum[i - 1, j] + abs(qs[i, j] - qs[i - 1, j])
        for p in range(npair):
            budget[p] = -1.0
    scratch = np.empty((8, 3, 3))
    for i in range(start, m):
        posed = False
        marked = False
        for p in range(npair):
            if budget[p] > 0.0:
                i0 = since[p]
                moved = 0.0
                for j in range(dof):
                    moved += weight[p, j] * (cum[i, j] - cum[i0, j])
                if moved < budget[p]:
                    continue
                if mover[p] >= 0:
                    # where it was proven, the body moved slower than anywhere: each
                    # joint's reach there, grown by at most what it has moved since
                    near = 0.0
                    for j in range(dof):
                        dj = cum[i, j] - cum[i0, j]
                        near += (rates[p, 0, j] + moved * rates[p, 1, j]) * dj
                    if near < budget[p]:
                        continue
            if not posed:
                _fk_into(qs[i], parent, origin, jtype, axis, src, scale, offset, poses)
                place_carried(frame, link, pose, carried, poses)
                posed = True
            rem = 0.0
            for j in range(dof):
                rem += weight[p, j] * (cum[m - 1, j] - cum[i, j])
            a, b = index[p, 0], index[p, 1]
            ta = poses[frame[a]] if frame[a] >= 0 else pose[a]
            tb = poses[frame[b]] if frame[b] >= 0 else pose[b]
            cap = pad + MARGIN + min(rem, horizon) + 1e-9
            lb = tree_lower_bound(ta, root[a], tb, root[b], center, axes, half, left, right,
                                  pad + MARGIN, cap, stack, gaps, scratch)
            if lb > pad + MARGIN:
                budget[p] = lb - pad - MARGIN
                since[p] = i
                mov = mover[p]
                if mov >= 0:
                    # the root's box alone: a sweep re-proves pairs too often to pay
                    # for more
                    local_rates(poses, ta if mov == a else tb, link[mov], root[mov], 0,
                                center, half, left, right, parent, jtype, axis, src, scale,
                                rates[p])
            else:
                out[i, p] = 1
                marked = True
                budget[p] = 0.0
        if marked and stop_early:
            return i
    return m
