"""A found path and its blended corners proven in one walk.

:func:`~arduinobot.planner.timing.curve.build_curve` certifies each corner's blend on its own, after
the path's proof: one certification per corner, each paying its fixed cost (the pairs
proven before the walk, a first bound for every pair, the samples checked first). Here
the blends at their full radius are walked with the path's edges, each right after the
edge that ends at its corner (its start a blend radius back along that edge, so a far
pair's bound carries over the short gap; walking back and forth to make the motion
continuous measured more bounds, not fewer). Measured in process, A/B interleaved, on the
peer bench's problems of course_fingers (arm and gripper) that need a detour: the path's
and its blends' proofs summed over them 141 -> 128 ms (self, 20), 70 -> 66 (pillars,
24), 54 -> 56 (table, 21: noise).

A refusal on an edge refuses the path (as the path's own proof would: the walk is as
sound, whatever it is walked with). Where a blend is refused, or a budget is spent, the
path is certified alone, as before, and the corners are left to ``build_curve`` (which
shrinks a colliding blend).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from arduinobot.planner.collision.proof.certificate import Certificate
from arduinobot.planner.collision.proof.certify import SAMPLE_STEP, Certifier
from arduinobot.planner.collision.proof.motion_check import StateChecker
from arduinobot.planner.timing.curve import Curve, build_curve


def prove_blended(proof: Certifier, path: np.ndarray, samples: StateChecker, *,
                  step: float = SAMPLE_STEP) -> tuple[Certificate, Curve | None]:
    """The certificate of ``path`` (shape (k, dof), its edges already checked at their
    samples) and, when the proof covers them too, its corners blended at
    ``build_curve``'s default radii (None: blend them with ``build_curve``).

    ``samples``: the world the blends' states are checked in first, ``step`` [rad]
    apart (a blend that really collides is refused there, not by a walk that converges
    on the contact; one that grazes between them is refused by the walk, and then
    blended by ``build_curve`` as before)."""
    curve = build_curve(path, None)
    starts, u1, u2, lengths, blends = _pieces(curve)
    if not blends.any():
        # no corner blended: the curve is the path's edges (collinear ones joined)
        cert = proof.path(path, sample_step=None)
        return cert, curve if cert.free else None
    states = np.concatenate([
        _blend_states(starts[k], u1[k], u2[k], lengths[k], step) for k in np.flatnonzero(blends)])
    if samples.first_invalid(states) >= 0:
        return proof.path(path, sample_step=None), None
    *motion, is_blend = _with_edges(path, starts, u1, u2, lengths, blends)
    cert = proof.pieces(*motion, sample_step=None)
    if cert.free:
        return cert, curve
    assert cert.failure is not None  # a refusal says where
    piece, _, _, dist = cert.failure
    if not is_blend[piece] and np.isfinite(dist):
        # a point of an edge closer than the clearance: the path is refused (a walk of
        # its edges alone would converge on the same graze, at the same cost again);
        # the failure names the path's edge, as the path's own proof would
        edge = int(np.count_nonzero(~is_blend[:piece]))
        return replace(cert, failure=(edge, *cert.failure[1:])), None
    # a blend refused, or a budget spent: the path's own proof decides it, the corners
    # built as before
    return proof.path(path, sample_step=None), None


def _pieces(curve: Curve) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                   np.ndarray]:
    # every piece of every section, and which are blends
    secs = curve.sections
    return (np.concatenate([s.starts for s in secs]), np.concatenate([s.u1 for s in secs]),
            np.concatenate([s.u2 for s in secs]), np.concatenate([s.lengths for s in secs]),
            np.concatenate([[k == "blend" for k in s.kinds] for s in secs]))


def _blend_states(start: np.ndarray, u1: np.ndarray, u2: np.ndarray, length: float,
                  step: float) -> np.ndarray:
    # |q'| <= 1 along a blend: parameter steps of ``step`` are joint steps <= it
    n = max(1, int(np.ceil(length / step)))
    x = np.linspace(0.0, 1.0, n + 1)[:, None]
    return start + u1 * (length * x) + (u2 - u1) * (length * (x**3 - 0.5 * x**4))


def _with_edges(path: np.ndarray, starts: np.ndarray, u1: np.ndarray, u2: np.ndarray,
                lengths: np.ndarray, blends: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    # the path's whole edges, each followed by the blend of the corner it ends at: one
    # motion for the walk (it accounts for the gaps between pieces; any order is as
    # sound, this one keeps the gaps short)
    d = np.diff(path, axis=0)
    n = np.linalg.norm(d, axis=1)
    u = np.divide(d, n[:, None], out=np.zeros_like(d), where=n[:, None] > 0)
    after: dict[int, list[int]] = {}
    for k in np.flatnonzero(blends):
        corner = starts[k] + 0.5 * lengths[k] * u1[k]  # a blend is 2 r long, r back
        e = int(np.argmin(np.abs(path[1:] - corner).max(axis=1)))
        after.setdefault(e, []).append(int(k))
    rows = []
    for e in range(len(d)):
        rows.append((path[e], u[e], u[e], n[e], False))
        rows.extend((starts[k], u1[k], u2[k], lengths[k], True) for k in after.get(e, ()))
    s, a, b, ln, kind = zip(*rows)
    return (np.array(s), np.array(a), np.array(b), np.array(ln, float),
            np.array(kind, np.bool_))
