"""How fast a body moves where it is now: a motion bound for the next step, not for all
configurations.

The certifier's bound per pair (:func:`planner.collision.advance.pair_weights`) holds in
every configuration: a joint moves a body's points by at most the farthest they ever get
from its axis, the whole arm stretched out. An arm folded near its base moves its hand
far slower than that, and conservative advancement near a contact then takes steps ten
or twenty times too short (each needing an exact distance). For a body moving relative
to a static one (a scene obstacle, the base), over a step ``h`` along a piece its points
move at most ``S h + Q h^2 / 2`` [m], where

- ``S = sum_k v_k r_k`` over the movable joints ``k`` above the body: ``v_k`` the joint's
  speed bound on the piece [rad per unit of sigma], ``r_k`` the body's distance from the
  joint's axis now (its bounding sphere's centre's distance plus its radius; 1 for a
  prismatic joint, whose points all move at ``v_k``);
- ``Q = V sum_k v_k`` over the revolute ones: ``r_k`` grows no faster than the body
  moves relative to joint ``k``'s axis, at most ``V`` [m per unit of sigma], the pair's
  every-configuration bound.
"""

from __future__ import annotations

import numba
import numpy as np

from ..kinematics.chain import FIXED, PRISMATIC


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
def local_step(poses: np.ndarray, link: int, center: np.ndarray, radius: float,
               parent: np.ndarray, jtype: np.ndarray, axis: np.ndarray, src: np.ndarray,
               scale: np.ndarray, u1: np.ndarray, u2: np.ndarray, bound: float,
               room: float) -> float:
    """The step [unit of sigma] over which the body of ``link`` (``center`` [m] in its
    frame, ``radius`` [m]; link poses ``poses`` now) moves at most ``room`` [m], on a
    piece of tangents ``u1`` -> ``u2``; ``bound`` is the pair's every-configuration
    bound ``V`` [m per unit of sigma]."""
    t = poses[link]
    w0 = t[0, 0] * center[0] + t[0, 1] * center[1] + t[0, 2] * center[2] + t[0, 3]
    w1 = t[1, 0] * center[0] + t[1, 1] * center[1] + t[1, 2] * center[2] + t[1, 3]
    w2 = t[2, 0] * center[0] + t[2, 1] * center[1] + t[2, 2] * center[2] + t[2, 3]
    rate = 0.0
    turning = 0.0
    k = link - 1
    while k >= 0:
        if jtype[k] != FIXED and src[k] >= 0:
            v = abs(scale[k]) * max(abs(u1[src[k]]), abs(u2[src[k]]))
            if jtype[k] == PRISMATIC:
                rate += v
            else:
                # the axis passes through the carried link's origin, along axis[k] there
                j = poses[k + 1]
                e0 = j[0, 0] * axis[k, 0] + j[0, 1] * axis[k, 1] + j[0, 2] * axis[k, 2]
                e1 = j[1, 0] * axis[k, 0] + j[1, 1] * axis[k, 1] + j[1, 2] * axis[k, 2]
                e2 = j[2, 0] * axis[k, 0] + j[2, 1] * axis[k, 1] + j[2, 2] * axis[k, 2]
                norm = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                d0, d1, d2 = w0 - j[0, 3], w1 - j[1, 3], w2 - j[2, 3]
                x0, x1, x2 = d1 * e2 - d2 * e1, d2 * e0 - d0 * e2, d0 * e1 - d1 * e0
                off = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2) / norm if norm > 0.0 else 0.0
                rate += v * (off + radius)
                turning += v
        k = parent[k] - 1
    spread = bound * turning
    den = rate + np.sqrt(rate * rate + 2.0 * spread * room)
    return 2.0 * room / den if den > 0.0 else np.inf
