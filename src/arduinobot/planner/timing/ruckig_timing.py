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

import numba
import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from arduinobot.contract.errors import TrajectoryError
from arduinobot.planner.path_limits import ActiveLimits, BatchDynamics, torque_coefficients
from arduinobot.planner.timing.curve import Curve, PathCurve
from arduinobot.planner.timing.trajectory import CurveTiming, RestProfile, ScalarProfile

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
        :mod:`arduinobot.planner.timing.curve_eval` evaluates (as :meth:`evaluate` does)."""
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


@numba.njit(cache=True, nogil=True)
def _least(budget, use, lo, hi):
    # min over samples [lo, hi) and joints of budget / use where use > _TINY (inf if
    # nothing is used): budget and use shape (m, dof)
    r = np.inf
    for i in range(lo, hi):
        for d in range(use.shape[1]):
            if use[i, d] > _TINY:
                x = budget[i, d] / use[i, d]
                if x < r:
                    r = x
    return r


@numba.njit(cache=True, nogil=True)
def _piece_bounds(d1, d2, d3, mt, bt, gt, V, A, J, E, first, line, vs, as_, js):
    """:meth:`JerkLimitedTiming.piece_limits`' bounds into ``vs, as_, js`` (each (n,)):
    per piece ``p``, samples ``first[p]:first[p + 1]`` of the |derivatives| ``d1, d2,
    d3`` and |torque coefficients| ``mt, bt, gt`` (each (m, dof)). Returns (0, -1), or
    (1, piece) where gravity alone exceeds the effort limit, or (2, piece) where no
    speed is feasible. The same arithmetic in the same order as the numpy it replaced
    (a minimum is exact in any order), so the same bounds."""
    n = first.shape[0] - 1
    m, dof = d1.shape
    slack = np.empty((m, dof))
    for i in range(m):
        for d in range(dof):
            slack[i, d] = E[d] - gt[i, d]
    for p in range(n):
        for i in range(first[p], first[p + 1]):
            for d in range(dof):
                if slack[i, d] <= 0:
                    return 1, p
    bud = np.empty((m, dof))
    use = np.empty((m, dof))
    for p in range(n):
        lo, hi = first[p], first[p + 1]
        for i in range(lo, hi):
            for d in range(dof):
                bud[i, d] = V[d]
        lv = _least(bud, d1, lo, hi)
        for i in range(lo, hi):
            for d in range(dof):
                bud[i, d] = 0.5 * A[d]
        la = _least(bud, d2, lo, hi)
        for i in range(lo, hi):
            for d in range(dof):
                bud[i, d] = 0.5 * slack[i, d]
        le = _least(bud, bt, lo, hi)
        v = min(lv, np.sqrt(min(la, le)))  # leave half of the a and effort budgets for sdd
        for i in range(lo, hi):
            for d in range(dof):
                bud[i, d] = J[d]
        j_free = _least(bud, d1, lo, hi)
        done = False
        for _ in range(30):
            w = v
            w3 = w ** 3.0
            for i in range(lo, hi):
                for d in range(dof):
                    bud[i, d] = A[d] - d2[i, d] * w * w
            a = _least(bud, d1, lo, hi)
            for i in range(lo, hi):
                for d in range(dof):
                    bud[i, d] = slack[i, d] - bt[i, d] * w * w
            a = min(a, _least(bud, mt, lo, hi))
            if not line[p]:
                # a blend's jerk has a term 3 q'' sd sdd: sdd keeps only what leaves
                # half the jerk budget to sddd (see piece_limits)
                for i in range(lo, hi):
                    for d in range(dof):
                        bud[i, d] = 0.5 * (J[d] - d3[i, d] * w3)
                        use[i, d] = 3 * d2[i, d] * w
                a = min(a, _least(bud, use, lo, hi))
            j = -1.0
            if a > 0:
                for i in range(lo, hi):
                    for d in range(dof):
                        bud[i, d] = J[d] - 3 * d2[i, d] * w * max(a, 0.0) - d3[i, d] * w3
                j = _least(bud, d1, lo, hi)
            if a > 0 and j > 0 and (line[p] or j > 0.25 * j_free):
                vs[p], as_[p], js[p] = v, a, j
                done = True
                break
            v = 0.8 * v
        if not done:
            return 2, p
    return 0, -1


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
        counts = np.where(np.array([kind == "blend" for kind in curve.kinds]),
                          _BLEND_SAMPLES, _LINE_SAMPLES)
        own = np.repeat(np.arange(n), counts)
        first = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        # each sample evaluated inside its own piece (by s, a piece's end is the next's
        # start): np.linspace(0, L, m) of every piece at once, as it computes it (i times
        # L / (m - 1), the last exactly L)
        i = np.arange(first[-1]) - first[:-1][own]
        sigma = i * (curve.lengths / (counts - 1))[own] + 0.0
        sigma[first[1:] - 1] = curve.lengths
        q, d1, d2, d3 = curve.jet(own, sigma)
        mt, bt, gt = torque_coefficients(self.dynamics, q, d1, d2)
        V, A, J, E = (np.ascontiguousarray(x, dtype=float) for x in
                      (limits.velocity, limits.acceleration, limits.jerk, limits.effort))
        d1, d2, d3, mt, bt, gt = (np.ascontiguousarray(np.abs(x)) for x in
                                  (d1, d2, d3, mt, bt, gt))
        line = np.array([kind == "line" for kind in curve.kinds])
        vs, as_, js = np.zeros(n), np.zeros(n), np.zeros(n)
        code, piece = _piece_bounds(d1, d2, d3, mt, bt, gt, V, A, J, E, first, line,
                                    vs, as_, js)
        if code == 1:
            raise TrajectoryError("gravity alone exceeds the effort limit on the path",
                                  details={"stage": "ruckig", "piece": int(piece)})
        if code == 2:
            raise TrajectoryError("no feasible path speed on a curve piece",
                                  details={"stage": "ruckig", "piece": int(piece)})
        return vs, as_, js

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
        tr = Trajectory(1)
        # ruckig's calculation can fail on a profile that sits exactly on a boundary
        # between its cases (a 0.943 rad piece at 11.79 rad/s, 47.17 rad/s^2, 471.7
        # rad/s^3 takes exactly 0.4 s: RuckigError "error in step 1"); limits a hair
        # lower (still within the robot's) leave the boundary
        for shave in (1.0, 1.0 - 1e-9):
            inp.max_velocity = [float(v) * shave]
            inp.max_acceleration = [float(a) * shave]
            inp.max_jerk = [float(j) * shave]
            try:
                res = self._otg.calculate(inp, tr)
                break
            except RuckigError as e:
                error = str(e).strip().splitlines()[0] if str(e).strip() else "RuckigError"
        else:
            raise TrajectoryError(f"ruckig failed on a curve piece: {error}",
                                  details={"stage": "ruckig", "length": float(length),
                                           "v0": float(v0), "v1": float(v1),
                                           "limits": [float(v), float(a), float(j)]})
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

    def rest_to_rest_floor(self, curve: Curve, limits: ActiveLimits) -> float:
        """A lower bound [s] on :meth:`parameterise`'s duration for a ``curve`` of straight
        lines (every section's pieces lines, as a curve that stops at each waypoint).

        A line's piece bounds (:meth:`piece_limits`) are at most its kinematic ones,
        ``min_i V_i / |u_i|`` (likewise for A and J; effort and the 0.8 rounds only
        lower them), and a section is some rest-to-rest motion of ``s`` over its length
        within its pieces' bounds; so it takes at least ruckig's time-optimal
        rest-to-rest time over that length under the loosest of those kinematic bounds.
        Without inverse dynamics: ~10 us a section. 0 if a section is not all lines."""
        secs = [c for c in curve.sections if c.length > _TINY]
        if not secs:
            return 0.0
        if any(k != "line" for c in secs for k in c.kinds):
            return 0.0
        lim = np.array([limits.velocity, limits.acceleration, limits.jerk], float)
        use = np.abs(np.concatenate([c.u1 for c in secs]))[None]  # (1, pieces, dof)
        with np.errstate(divide="ignore"):
            piece = np.where(use > _TINY, lim[:, None, :] / use, np.inf).min(axis=2)
        first = np.concatenate([[0], np.cumsum([len(c.lengths) for c in secs])[:-1]])
        loosest = np.maximum.reduceat(piece, first, axis=1)  # (3, sections)
        if not (np.all(np.isfinite(loosest)) and np.all(loosest > 0)):
            return 0.0
        total = 0.0
        for c, (v, a, j) in zip(secs, loosest.T):
            try:
                total += self._piece(c.length, 0.0, 0.0, float(v), float(a), float(j)).duration
            except TrajectoryError:  # no floor then: the caller times the curve
                return 0.0
        return total

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
