"""How fast a body moves where it is now: a motion bound for the next step, not for all
configurations.

The certifier's bound per pair (:func:`arduinobot.planner.collision.proof.advance.pair_weights`) holds in
every configuration: a joint moves a body's points by at most the farthest they ever get
from its axis, the whole arm stretched out. An arm folded near its base moves its hand
far slower than that, and conservative advancement near a contact then takes steps ten
or twenty times too short (each needing an exact distance). For a body moving relative
to a static one (a scene obstacle, the base), over a step ``h`` along a piece its points
move at most ``S h + Q h^2 / 2`` [m], where

- ``S = sum_k v_k r_k`` over the movable joints ``k`` above the body: ``v_k`` the joint's
  speed bound on the piece [rad per unit of sigma], ``r_k`` the body's distance from the
  joint's axis now (the largest over a few of its OBB tree's nodes of a node's centre's
  distance plus its half diagonal; 1 for a prismatic joint, whose points all move at
  ``v_k``);
- ``Q = V sum_k v_k`` over the revolute ones: ``r_k`` grows no faster than the body
  moves relative to joint ``k``'s axis, at most ``V`` [m per unit of sigma], the pair's
  every-configuration bound.
"""

from __future__ import annotations

import numba
import numpy as np

from arduinobot.planner.kinematics.chain import FIXED, PRISMATIC, Chain


@numba.njit(cache=True, nogil=True)
def movable_above(link: int, parent: np.ndarray, jtype: np.ndarray, src: np.ndarray) -> int:
    """How many joints move ``link`` (a link index; a scene body's -1: none)."""
    n = 0
    k = link - 1  # joint k carries link k + 1
    while k >= 0:
        if jtype[k] != FIXED and src[k] >= 0:
            n += 1
        k = parent[k] - 1
    return n


@numba.njit(cache=True, nogil=True)
def local_rates(poses: np.ndarray, t: np.ndarray, link: int, root: int, depth: int,
                center: np.ndarray, half: np.ndarray, left: np.ndarray, right: np.ndarray,
                parent: np.ndarray, jtype: np.ndarray, axis: np.ndarray, src: np.ndarray,
                scale: np.ndarray, out: np.ndarray) -> None:
    """Per actuated joint ``j``: how fast a body carried by ``link`` (its pose ``t``
    (4, 4); its OBB tree from node ``root`` of a :class:`.obbtree.Forest`'s arrays; link
    poses ``poses`` now; the :class:`~arduinobot.planner.kinematics.chain.Chain`'s arrays, which
    the caller unpacks once: this runs per step) moves per unit of ``q_j`` where it is
    now (``out[0, j]`` [m/rad]), and how many of its revolute joints follow ``q_j``
    (``out[1, j]``, mimics by their multipliers: each lets ``r_k`` grow).

    A joint's ``r_k`` is the largest, over the tree's nodes ``depth`` levels down (they
    hold every triangle), of a node's centre's distance from the axis plus its box's half
    diagonal: a long link is a few short pieces, each as far from the axis as it is
    (``2**depth`` pieces at most, each a few flops per joint).
    """
    rate, turn = out[0], out[1]
    frontier = np.empty((2 ** depth, 4))  # world centre and radius of each piece
    stack = np.empty((2 ** depth + depth + 1, 2), np.int64)
    n, top = 0, 1
    stack[0, 0], stack[0, 1] = root, 0
    while top > 0:
        top -= 1
        node, level = stack[top, 0], stack[top, 1]
        if level < depth and left[node] >= 0:
            stack[top, 0], stack[top, 1] = left[node], level + 1
            stack[top + 1, 0], stack[top + 1, 1] = right[node], level + 1
            top += 2
            continue
        c = center[node]
        for r in range(3):
            frontier[n, r] = t[r, 0] * c[0] + t[r, 1] * c[1] + t[r, 2] * c[2] + t[r, 3]
        h = half[node]
        frontier[n, 3] = np.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2])
        n += 1
    rate[:] = 0.0
    turn[:] = 0.0
    k = link - 1  # joint k carries link k + 1
    while k >= 0:
        j = src[k]
        if jtype[k] != FIXED and j >= 0:
            if jtype[k] == PRISMATIC:
                rate[j] += abs(scale[k])
            else:
                # the axis passes through the carried link's origin, along axis[k] there
                a = poses[k + 1]
                e0 = a[0, 0] * axis[k, 0] + a[0, 1] * axis[k, 1] + a[0, 2] * axis[k, 2]
                e1 = a[1, 0] * axis[k, 0] + a[1, 1] * axis[k, 1] + a[1, 2] * axis[k, 2]
                e2 = a[2, 0] * axis[k, 0] + a[2, 1] * axis[k, 1] + a[2, 2] * axis[k, 2]
                norm = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                reach = 0.0
                for i in range(n):
                    d0 = frontier[i, 0] - a[0, 3]
                    d1 = frontier[i, 1] - a[1, 3]
                    d2 = frontier[i, 2] - a[2, 3]
                    x0, x1, x2 = d1 * e2 - d2 * e1, d2 * e0 - d0 * e2, d0 * e1 - d1 * e0
                    off = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2) / norm if norm > 0.0 else 0.0
                    reach = max(reach, off + frontier[i, 3])
                rate[j] += abs(scale[k]) * reach
                turn[j] += abs(scale[k])
        k = parent[k] - 1


@numba.njit(cache=True, nogil=True)
def local_step(rate: np.ndarray, turn: np.ndarray, u1: np.ndarray, u2: np.ndarray,
               bound: float, room: float) -> float:
    """The step [unit of sigma] over which a body of :func:`local_rates` ``rate`` and
    ``turn`` moves at most ``room`` [m], on a piece of tangents ``u1`` -> ``u2``;
    ``bound`` is the pair's every-configuration bound ``V`` [m per unit of sigma]."""
    s = 0.0
    spread = 0.0
    for j in range(rate.shape[0]):
        v = max(abs(u1[j]), abs(u2[j]))
        s += rate[j] * v
        spread += turn[j] * v
    spread *= bound
    den = s + np.sqrt(s * s + 2.0 * spread * room)
    return 2.0 * room / den if den > 0.0 else np.inf


@numba.njit(cache=True, nogil=True)
def moving_by_static(a: int, b: int, body_frame: np.ndarray, chain: Chain) -> int:
    """Of bodies ``a`` and ``b`` (indices into ``body_frame``, their link or -1), the one
    that moves when the other does not; -1 if both move or neither does."""
    fa, fb = body_frame[a], body_frame[b]
    ma = movable_above(fa, chain.parent, chain.jtype, chain.src) if fa >= 0 else 0
    mb = movable_above(fb, chain.parent, chain.jtype, chain.src) if fb >= 0 else 0
    if (ma == 0) == (mb == 0):
        return -1
    return a if ma > 0 else b
