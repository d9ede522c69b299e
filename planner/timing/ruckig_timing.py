"""Jerk-limited timing along the curve with ruckig (the default profile).

Each piece of a curve section (a straight edge or a corner blend) gets a one-degree-of-
freedom ruckig profile of the path parameter ``s``. Because the joints follow ``c(s)``,
this is exactly ruckig's phase-synchronised motion on a straight edge (all joints share
one profile shape, so the motion stays on the edge), and on a blend it stays on the
re-checked blend. Per piece we bound ``sd``, ``sdd``, ``sddd`` so that, at every sampled
point of the piece and with margin for the curvature terms::

    |c'| v <= vmax,  |c'| a + |c''| v^2 <= amax,
    |c'| j + 3 |c''| v a + |c'''| v^3 <= jmax,  |m| a + |b| v^2 + |g| <= effort

Pieces meet with ``sdd = 0``; the path velocity at each junction is chosen by a forward
and a backward pass over closed-form jerk-limited distances, so every piece is reachable
without overshoot. Stops (hard corners) end a section at rest. Offline ruckig only: no
intermediate waypoints (the community build would call a remote API for them).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from ..errors import TrajectoryError
from ..path_limits import ActiveLimits, BatchDynamics, torque_coefficients
from .curve import Curve, PathCurve
from .trajectory import CurveTiming, RestProfile, ScalarProfile

log = logging.getLogger(__name__)

_LINE_SAMPLES = 9
_BLEND_SAMPLES = 17
_TINY = 1e-12


class RuckigProfile:
    """Piecewise ruckig profiles of ``s``, evaluated from their polynomial phases."""

    def __init__(self, pieces: Sequence[tuple[float, Trajectory]]) -> None:
        # (s offset, trajectory); each phase: start time, and (p, v, a, j) at it
        starts, coeffs = [], []
        t = 0.0
        for s_off, tr in pieces:
            prof = tr.profiles[0][0]
            if prof.brake.duration > 0 or prof.accel.duration > 0:
                raise TrajectoryError("ruckig needed a brake pre-trajectory: the boundary "
                                      "state exceeded the piece's limits",
                                      details={"stage": "ruckig"})
            tt = t
            for i in range(7):
                starts.append(tt)
                coeffs.append((s_off + prof.p[i], prof.v[i], prof.a[i], prof.j[i]))
                tt += prof.t[i]
            t += tr.duration
        self._start = np.array(starts)
        self._c = np.array(coeffs).reshape(-1, 4)
        self.duration = t
        self._end = (s_off + pieces[-1][1].profiles[0][0].pf) if pieces else 0.0

    def polynomial(self) -> tuple[np.ndarray, np.ndarray, float, float]:
        """(phase start times, (p, v, a, j) at each, shape (n, 4), duration, end s): what
        :mod:`planner.timing.curve_eval` evaluates (as :meth:`evaluate` does)."""
        return self._start, self._c, self.duration, self._end

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ts = np.clip(np.asarray(ts, float), 0.0, self.duration)
        k = np.clip(np.searchsorted(self._start, ts, side="right") - 1, 0, len(self._start) - 1)
        dt = ts - self._start[k]
        p, v, a, j = self._c[k].T
        s = p + dt * (v + dt * (a / 2 + dt * j / 6))
        sd = v + dt * (a + dt * j / 2)
        sdd = a + dt * j
        end = ts >= self.duration
        s[end], sd[end], sdd[end] = self._end, 0.0, 0.0
        return s, sd, sdd


def _speed_change_distance(v0: float, v1: float, a: float, j: float) -> float:
    """Distance to change speed v0 -> v1 with sdd = 0 at both ends, limits a, j (time-optimal)."""
    dv = abs(v1 - v0)
    t = dv / a + a / j if dv >= a * a / j else 2.0 * math.sqrt(dv / j)
    return 0.5 * (v0 + v1) * t


def _max_speed_within(v_other: float, dist: float, a: float, j: float, cap: float) -> float:
    """Largest v <= cap that can reach/leave ``v_other`` within ``dist``."""
    if v_other >= cap or _speed_change_distance(v_other, cap, a, j) <= dist:
        return cap
    lo, hi = v_other, cap
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _speed_change_distance(v_other, mid, a, j) <= dist:
            lo = mid
        else:
            hi = mid
    return lo


class JerkLimitedTiming:
    """Jerk-limited time parameterisation of a :class:`Curve`.

    Args:
        dynamics: anything with ``torques_batch`` (the effort limit is enforced through it).
    """

    def __init__(self, dynamics: BatchDynamics) -> None:
        self.dynamics = dynamics
        self._otg = Ruckig(1)

    def piece_limits(self, curve: PathCurve, limits: ActiveLimits
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Constant (v, a, j) bounds on (sd, sdd, sddd) per piece, each shape (n,)."""
        n = len(curve.lengths)
        counts = [_BLEND_SAMPLES if kind == "blend" else _LINE_SAMPLES for kind in curve.kinds]
        own = np.repeat(np.arange(n), counts)
        # each sample evaluated inside its own piece (by s, a piece's end is the next's start)
        sigma = np.concatenate([np.linspace(0.0, L, m) for L, m in zip(curve.lengths, counts)])
        q, d1, d2, d3 = curve.jet(own, sigma)
        mt, bt, gt = torque_coefficients(self.dynamics, q, d1, d2)
        V, A, J, E = limits.velocity, limits.acceleration, limits.jerk, limits.effort
        d1, d2, d3, mt, bt, gt = (np.abs(x) for x in (d1, d2, d3, mt, bt, gt))
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])

        def least(budget: np.ndarray, use: np.ndarray) -> np.ndarray:
            # per piece: min over its samples and joints of budget / use where use > 0
            # (inf if nothing is used), shape (n,); all pieces at once, not a loop
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.where(use > _TINY, np.broadcast_to(budget, use.shape) / use, np.inf)
            return np.minimum.reduceat(r.min(axis=1), first)

        slack_e = E - gt
        short = np.flatnonzero(np.minimum.reduceat((slack_e <= 0).any(axis=1), first))
        if len(short):
            raise TrajectoryError("gravity alone exceeds the effort limit on the path",
                                  details={"stage": "ruckig", "piece": int(short[0])})
        # leave half of the acceleration and effort budgets for sdd
        v = np.minimum(least(V, d1), np.sqrt(np.minimum(least(0.5 * A, d2),
                                                        least(0.5 * slack_e, bt))))
        line = np.array([kind == "line" for kind in curve.kinds])
        j_free = least(J, d1)
        done = np.zeros(n, dtype=bool)
        vs, as_, js = v.copy(), np.zeros(n), np.zeros(n)
        for _ in range(30):
            w = v[own][:, None]
            a = np.minimum(least(A - d2 * w * w, d1), least(slack_e - bt * w * w, mt))
            # a blend's jerk has a term 3 q'' sd sdd: sdd at its bound would leave a
            # sharp blend almost no speed, yet a blend mostly cruises; so sdd keeps only
            # what leaves half the jerk budget to sddd, and the speed stays high
            a = np.where(line, a, np.minimum(a, least(0.5 * (J - d3 * w**3), 3 * d2 * w)))
            j = np.where(a > 0, least(J - 3 * d2 * w * np.maximum(a, 0)[own][:, None]
                                      - d3 * w**3, d1), -1.0)
            ok = ~done & (a > 0) & (j > 0) & (line | (j > 0.25 * j_free))
            vs[ok], as_[ok], js[ok] = v[ok], a[ok], j[ok]
            done |= ok
            if done.all():
                return vs, as_, js
            v = np.where(done, v, 0.8 * v)
        raise TrajectoryError("no feasible path speed on a curve piece",
                              details={"stage": "ruckig", "piece": int(np.argmin(done))})

    def section(self, curve: PathCurve, limits: ActiveLimits, *,
                blend_speed: bool = True,
                bounds: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                ) -> RuckigProfile:
        """The profile of one section, from rest to rest.

        ``blend_speed=False`` stops at every junction (the per-piece rest-to-rest baseline).
        ``bounds``: the section's :meth:`piece_limits` when the caller has them.
        """
        vs, as_, js = self.piece_limits(curve, limits) if bounds is None else bounds
        n = len(vs)
        L = curve.lengths
        vb = np.zeros(n + 1)
        if blend_speed:
            for k in range(1, n):
                vb[k] = min(vs[k - 1], vs[k]) * (1 - 1e-9)
            for k in range(n - 1, 0, -1):  # backward: able to slow down to vb[k + 1]
                vb[k] = _max_speed_within(vb[k + 1], L[k] * (1 - 1e-9), as_[k], js[k], vb[k])
            for k in range(1, n):  # forward: able to speed up from vb[k - 1]
                vb[k] = _max_speed_within(vb[k - 1], L[k - 1] * (1 - 1e-9), as_[k - 1],
                                          js[k - 1], vb[k])
        pieces: list[tuple[float, Trajectory]] = []
        for k in range(n):
            tr = self._piece(L[k], vb[k], vb[k + 1], vs[k], as_[k], js[k])
            pieces.append((float(curve.s0[k]), tr))
        return RuckigProfile(pieces)

    def _piece(self, length: float, v0: float, v1: float, v: float, a: float,
               j: float) -> Trajectory:
        inp = InputParameter(1)
        inp.current_position = [0.0]
        inp.current_velocity = [v0]
        inp.current_acceleration = [0.0]
        inp.target_position = [float(length)]
        inp.target_velocity = [v1]
        inp.target_acceleration = [0.0]
        inp.max_velocity = [float(v)]
        inp.max_acceleration = [float(a)]
        inp.max_jerk = [float(j)]
        tr = Trajectory(1)
        res = self._otg.calculate(inp, tr)
        if res not in (Result.Working, Result.Finished):
            raise TrajectoryError(f"ruckig failed on a curve piece: {res}",
                                  details={"stage": "ruckig", "result": str(res),
                                           "length": float(length), "v0": v0, "v1": v1,
                                           "limits": [v, a, j]})
        ext = tr.position_extrema[0]
        if ext.min < -1e-9 or ext.max > length + 1e-9:
            raise TrajectoryError("ruckig overshot a curve piece",
                                  details={"stage": "ruckig", "min": ext.min, "max": ext.max,
                                           "length": float(length)})
        return tr

    def parameterise(self, curve: Curve, limits: ActiveLimits, *,
                     blend_speed: bool = True) -> CurveTiming:
        """Time every section of ``curve``; raises TrajectoryError if ruckig fails (a
        piece named in its details counts the pieces of every moving section)."""
        moving = [c for c in curve.sections if c.length > _TINY]
        secs: list[tuple[PathCurve, ScalarProfile]] = []
        if moving:
            # every section's piece limits in one batch (one dynamics call, one pass of
            # numpy work): a curve that stops at each waypoint has a section per edge
            def joined(f: str) -> np.ndarray:
                return np.concatenate([getattr(c, f) for c in moving])

            whole = PathCurve(joined("starts"), joined("u1"), joined("u2"), joined("lengths"),
                              [k for c in moving for k in c.kinds])
            bounds = self.piece_limits(whole, limits)
            ends = np.cumsum([len(c.lengths) for c in moving])[:-1]
            for c, *own in zip(moving, *(np.split(b, ends) for b in bounds)):
                secs.append((c, self.section(c, limits, blend_speed=blend_speed,
                                             bounds=tuple(own))))
        if not secs:
            secs.append((curve.sections[0], RestProfile()))
        return CurveTiming(secs, goal=curve.goal)
