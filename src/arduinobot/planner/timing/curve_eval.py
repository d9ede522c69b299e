"""Joint states of a curve timed by polynomial profiles, in one compiled pass.

:meth:`CurveTiming.evaluate <arduinobot.planner.timing.trajectory.CurveTiming.evaluate>` in numpy
costs ~0.2 us a state in temporaries and index gathers (a section mask, the profile's
phase lookup, the curve's piece lookup, three derivative arrays): the verifier's limit
grid has thousands of states per motion, so that was a third of its time. Here every
state is one loop iteration doing the same arithmetic in the same order (so the states
equal numpy's to rounding, ~1e-16 relative), for timings whose every section's profile
is piecewise cubic in time (ruckig's phases, a rest).

Layout (:func:`pack`): sections ``i`` with start times ``t0[i]``; section ``i``'s profile
phases ``phase[ph0[i]:ph0[i + 1]]`` (start time, and ``p, v, a, j`` at it), its
duration and end ``s``; its curve pieces ``piece[pc0[i]:pc0[i + 1]]`` (``s0``, length,
start point, tangents ``u1``, ``u2``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import numba
import numpy as np

if TYPE_CHECKING:
    from arduinobot.planner.timing.curve import PathCurve


class Packed(NamedTuple):
    """The arrays :func:`states` reads (see the module docstring)."""

    t0: np.ndarray          # (nsec,)
    ph0: np.ndarray         # (nsec + 1,) int64
    ph_start: np.ndarray    # (nph,)
    ph_c: np.ndarray        # (nph, 4): p, v, a, j
    sec_dur: np.ndarray     # (nsec,)
    sec_end: np.ndarray     # (nsec,) the profile's s at its end
    pc0: np.ndarray         # (nsec + 1,) int64
    s0: np.ndarray          # (npc,)
    lengths: np.ndarray     # (npc,)
    starts: np.ndarray      # (npc, dof)
    u1: np.ndarray          # (npc, dof)
    u2: np.ndarray          # (npc, dof)
    curve_len: np.ndarray   # (nsec,) each section curve's length
    line: np.ndarray        # (npc,) bool: u1 == u2 (no turn: x**3, x**4 meet only 0)
    goal: np.ndarray        # (dof,)
    duration: float


def pack(t0: np.ndarray,
         sections: Sequence[tuple[PathCurve, tuple[np.ndarray, np.ndarray, float, float]]],
         goal: np.ndarray, duration: float) -> Packed:
    """``sections``: (PathCurve, (phase starts, phase coefficients (n, 4), duration, end s))."""
    ph0, pc0 = [0], [0]
    starts, coeffs, durs, ends = [], [], [], []
    s0, lengths, pstarts, u1, u2, clen = [], [], [], [], [], []
    for curve, (ps, pc, dur, end) in sections:
        starts.append(ps)
        coeffs.append(pc)
        ph0.append(ph0[-1] + len(ps))
        durs.append(dur)
        ends.append(end)
        s0.append(curve.s0)
        lengths.append(curve.lengths)
        pstarts.append(curve.starts)
        u1.append(curve.u1)
        u2.append(curve.u2)
        pc0.append(pc0[-1] + len(curve.lengths))
        clen.append(curve.length)
    cat = np.concatenate
    return Packed(np.ascontiguousarray(t0, float), np.array(ph0, np.int64), cat(starts),
                  np.ascontiguousarray(cat(coeffs).reshape(-1, 4)), np.array(durs, float),
                  np.array(ends, float), np.array(pc0, np.int64), cat(s0), cat(lengths),
                  np.ascontiguousarray(cat(pstarts)), np.ascontiguousarray(cat(u1)),
                  np.ascontiguousarray(cat(u2)), np.array(clen, float),
                  np.all(cat(u1) == cat(u2), axis=1), np.ascontiguousarray(goal, float),
                  float(duration))


def states(p: Packed, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, qd, qdd) at times ``ts`` (clamped to [0, duration]), each (m, dof)."""
    ts = np.ascontiguousarray(np.atleast_1d(ts), dtype=float)
    dof = p.goal.shape[0]
    q = np.empty((len(ts), dof))
    qd = np.empty_like(q)
    qdd = np.empty_like(q)
    _states(ts, p.t0, p.ph0, p.ph_start, p.ph_c, p.sec_dur, p.sec_end, p.pc0, p.s0,
            p.lengths, p.starts, p.u1, p.u2, p.curve_len, p.line, p.goal, p.duration, q, qd,
            qdd)
    return q, qd, qdd


@numba.njit(cache=True, nogil=True)
def _last_le(a, lo, hi, x):
    # the last index in [lo, hi) with a[i] <= x (searchsorted 'right' - 1), clamped to
    # [lo, hi - 1]: numpy's lookups then np.clip, as the numpy evaluators do them
    i, j = lo, hi
    while i < j:
        mid = (i + j) // 2
        if a[mid] <= x:
            i = mid + 1
        else:
            j = mid
    return max(lo, min(i - 1, hi - 1))


@numba.njit(cache=True, nogil=True)
def _states(ts, t0, ph0, ph_start, ph_c, sec_dur, sec_end, pc0, s0, lengths, starts, u1, u2,
            curve_len, line, goal, duration, q, qd, qdd):
    nsec = t0.shape[0]
    dof = goal.shape[0]
    for m in range(ts.shape[0]):
        t = min(max(ts[m], 0.0), duration)
        if t >= duration:  # the final state is exact: the goal, at rest
            for d in range(dof):
                q[m, d] = goal[d]
                qd[m, d] = 0.0
                qdd[m, d] = 0.0
            continue
        i = _last_le(t0, 0, nsec, t)
        # the section's profile (RuckigProfile.evaluate)
        tl = min(max(t - t0[i], 0.0), sec_dur[i])
        if tl >= sec_dur[i]:
            s, sd, sdd = sec_end[i], 0.0, 0.0
        else:
            k = _last_le(ph_start, ph0[i], ph0[i + 1], tl)
            dt = tl - ph_start[k]
            pp, v, a, j = ph_c[k, 0], ph_c[k, 1], ph_c[k, 2], ph_c[k, 3]
            s = pp + dt * (v + dt * (a / 2 + dt * j / 6))
            sd = v + dt * (a + dt * j / 2)
            sdd = a + dt * j
        # the curve's piece (PathCurve.locate, then jet orders 0, 1, 2)
        s = min(max(s, 0.0), curve_len[i])
        k = _last_le(s0, pc0[i], pc0[i + 1], s)
        L = lengths[k]
        sigma = min(max(s - s0[k], 0.0), L)
        x = sigma / L if L > 0 else 0.0
        inv_l = 1.0 / L if L > 0 else 0.0
        x2 = x * x  # as numpy: x**2 a square, x**3 and x**4 through pow()
        x3 = 0.0
        x4 = 0.0
        if not line[k]:
            # on a line u2 - u1 is +0.0, so every term below meets it as +0.0 (the
            # polynomials are finite and >= 0 on [0, 1]) whatever x**3, x**4 are: the
            # same numbers without pow(), ~2/3 of a state's time
            x3 = x ** 3.0
            x4 = x ** 4.0
        h0 = x3 - 0.5 * x4
        h1 = 3 * x2 - 2 * x3
        h2 = 6 * x - 6 * x2
        sd2 = sd * sd
        for d in range(dof):
            a1 = u1[k, d]
            du = u2[k, d] - a1
            c0 = starts[k, d] + a1 * sigma + du * L * h0
            c1 = a1 + du * h1
            c2 = du * h2 * inv_l
            q[m, d] = c0
            qd[m, d] = c1 * sd
            qdd[m, d] = c1 * sdd + c2 * sd2
