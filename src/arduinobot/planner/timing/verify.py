"""Verify a trajectory before it is returned: every limit between samples, and collisions.

Per joint, the worst ratio of each quantity to its limit (position: ``|q - mid| /
half_range``). Position, velocity, acceleration and effort are checked at every sample
and on a fine time grid between them (toppra bounds torque only at its gridpoints, and a
blend's torque can peak between two samples); jerk by finite differences of the sampled
accelerations (the mean jerk over each interval), as a motor controller sees it. A ratio
passes if it is <= 1 + ``TOLERANCE`` (1e-6 relative): only the rounding of limits met
exactly (ruckig saturates its limits) is forgiven.

Collisions: the certificate of the curve the trajectory follows decides them over the
whole continuous motion (:mod:`arduinobot.planner.collision.proof.certify`). Without one, states at most
``step`` (0.002 rad) apart are checked with ``first_invalid``, and the minimum clearance,
an FCL distance query (~ms per state), is measured on ``clearance_states`` of them.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Protocol

import numba
import numpy as np

from arduinobot.planner.checks import CHECK_STEP
from arduinobot.planner.collision.proof.certificate import Certificate
from arduinobot.planner.path_limits import BatchDynamics, Derating, LimitsLike
from arduinobot.planner.timing.trajectory import JointTrajectory

log = logging.getLogger(__name__)

TOLERANCE = 1e-6
QUANTITIES = ("position", "velocity", "acceleration", "jerk", "effort")


class _World(Protocol):
    def first_invalid(self, qs: np.ndarray) -> int: ...
    def min_clearance(self, qs: np.ndarray) -> tuple[float, tuple[str, str]]: ...
    def check(self, q: np.ndarray, *, clearance: bool = False): ...


@dataclass(frozen=True)
class VerificationReport:
    """What the verifier found.

    Attributes:
        ok: every enforced ratio <= 1 + tolerance, no collision, and every value finite.
        joint_names: column order of ``ratios``.
        ratios: quantity -> worst ratio to the limit per joint (1.0 = at the limit).
        worst: quantity -> worst ratio over joints.
        enforced: quantities that must pass (jerk is not enforced for time-optimal profiles:
            toppra cannot limit it; its ratio is still reported).
        violations: the enforced quantities over 1 + tolerance.
        collision_free: certified free over the whole continuous motion (``certified``),
            or, for a trajectory given without a certificate, no dense state collides.
        colliding_time: time [s] of the first colliding state, if any; ``colliding_pairs`` its pairs.
        checked_states: dense states collision-checked (0 when certified); ``max_step`` the
            largest joint step [rad] between them (0 when certified).
        min_clearance: [m] when certified, a lower bound on the distance over the whole
            motion (every checked pair, every point between samples); else measured on
            ``clearance_states`` states. ``closest_pair`` is its pair.
        certified: collisions were decided by the curve's certificate
            (:mod:`arduinobot.planner.collision.proof.certify`), not by sampling.
        derating: factors applied to the limits to get here; ``attempts`` timings tried.
        tolerance: relative tolerance on the ratios.
        finite: every time, position, velocity, acceleration, jerk and effort of the
            trajectory (samples and the grid between them) is a finite number.
        rungs: when certified, how often each rung of the proof's near-contact ladder
            was used (:class:`arduinobot.planner.collision.proof.certificate.Rungs`, by
            field name); None otherwise.
    """

    ok: bool
    joint_names: tuple[str, ...]
    ratios: Mapping[str, tuple[float, ...]]
    worst: Mapping[str, float]
    enforced: tuple[str, ...]
    violations: tuple[str, ...]
    collision_free: bool
    colliding_time: float | None
    colliding_pairs: tuple[tuple[str, str], ...]
    checked_states: int
    max_step: float
    min_clearance: float
    closest_pair: tuple[str, str]
    clearance_states: int
    derating: Derating = field(default_factory=Derating)
    attempts: int = 1
    tolerance: float = TOLERANCE
    certified: bool = False
    finite: bool = True
    rungs: Mapping[str, int] | None = None

    @property
    def worst_overall(self) -> tuple[str, float]:
        """The enforced quantity closest to (or furthest over) its limit, and its ratio."""
        q = max(self.enforced, key=lambda k: self.worst[k])
        return q, self.worst[q]

    def to_dict(self) -> dict[str, object]:
        wq, wr = self.worst_overall
        return {"ok": self.ok, "joint_names": list(self.joint_names),
                "ratios": {k: list(v) for k, v in self.ratios.items()},
                "worst": dict(self.worst), "worst_overall": {"quantity": wq, "ratio": wr},
                "enforced": list(self.enforced), "violations": list(self.violations),
                "collision_free": self.collision_free, "colliding_time": self.colliding_time,
                "colliding_pairs": [list(p) for p in self.colliding_pairs],
                "checked_states": self.checked_states, "max_step": self.max_step,
                "min_clearance": self.min_clearance if math.isfinite(self.min_clearance)
                else None,
                "closest_pair": list(self.closest_pair),
                "clearance_states": self.clearance_states,
                "derating": self.derating.to_dict(), "attempts": self.attempts,
                "tolerance": self.tolerance, "certified": self.certified,
                "finite": self.finite,
                "rungs": None if self.rungs is None else dict(self.rungs)}

    def to_json(self) -> str:
        return json.dumps(self.to_dict())


@numba.njit(cache=True, nogil=True)
def _peak_into(v, centre, peak):
    # peak[d] = max(peak[d], max_i |v[i, d] - centre[d]|), a NaN kept (as np.max keeps
    # it): numpy's abs, max and maximum over an (m, dof) array cost ~20 us a call
    for i in range(v.shape[0]):
        for d in range(v.shape[1]):
            a = abs(v[i, d] - centre[d])
            if a > peak[d] or a != a:
                peak[d] = a if peak[d] == peak[d] else peak[d]


def _peak(values: tuple[np.ndarray, ...], centre: np.ndarray | None, dof: int) -> np.ndarray:
    """Per joint the largest ``|value - centre|`` over every array of ``values`` (each
    shape (m, dof)), shape (dof,): 0 where there are none."""
    peak = np.zeros(dof)
    c = np.zeros(dof) if centre is None else np.ascontiguousarray(centre, float)
    for v in values:
        if len(v):
            _peak_into(np.asarray(v, float), c, peak)
    return peak


def _of_peaks(limit: np.ndarray, peak: np.ndarray) -> np.ndarray:
    # peak / limit elementwise, any shape; a zero limit with motion is inf
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(limit > 0, peak / np.where(limit > 0, limit, 1.0),
                        np.where(peak > 0, np.inf, 0.0))


class Verifier:
    """Checks trajectories against the limits, the dynamics and the collision world.

    Args:
        limits: position limits and the (request-scaled) velocity/acceleration/jerk/effort.
        dynamics: anything with ``torques_batch``.
        world: a CollisionWorld (``first_invalid``, ``min_clearance``, ``check``).
        step: max joint step [rad] between collision-checked states.
        clearance_states: states the clearance is measured on (0 to skip).
    """

    def __init__(self, limits: LimitsLike, dynamics: BatchDynamics, world: _World, *,
                 step: float = CHECK_STEP, clearance_states: int = 3) -> None:
        self.limits = limits
        self.dynamics = dynamics
        self.world = world
        self.step = step
        self.clearance_states = clearance_states

    def fine_states(self, traj: JointTrajectory
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """(times, q, qd, qdd, 1) on a uniform time grid fine enough that no joint moves
        more than ``step / 4`` between states (from the sampled peak speed plus the
        acceleration limit times half a sample interval): every limit, and collisions."""
        if traj.duration <= 0.0:
            t = np.array([0.0])
            return (t, *traj.evaluate(t), 1)
        h = float(np.max(np.diff(traj.times))) if len(traj.times) > 1 else traj.duration
        vpeak = float(np.max(np.abs(traj.velocities)
                             + 0.5 * h * np.asarray(self.limits.acceleration)[None, :]))
        n = max(2, int(math.ceil(traj.duration * vpeak / (0.25 * self.step))) + 1)
        t = np.linspace(0.0, traj.duration, n)
        return (t, *traj.evaluate(t), 1)

    def limit_states(self, traj: JointTrajectory
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """(times, q, qd, qdd, stride) on a uniform time grid for the limits alone
        (collisions proven otherwise), fine enough that between two grid states each
        velocity and acceleration passes its grid maximum by at most 0.5% of its limit.

        An acceleration that keeps the jerk limit ``j`` moves at most ``h j / 2`` past
        its grid values in a step ``h``, so ``h`` is at most 1% of the shortest ``a/j``
        (at least 0.25 ms, at most the sample interval). A velocity moves at most
        ``h A / 2`` past them, ``A`` the joint's peak acceleration: its grid maximum plus
        ``h j / 2``, at most the limit ``a``. ``h`` is also at most ``1% v / A``; where
        the first grid is coarser than that, it is refined. Joints the trajectory never
        moves (a closed gripper during an arm motion) have nothing to resolve.

        Effort (``M(q) qdd + c(q, qd) + g(q)``) changes at the rate of acceleration, so
        every ``stride``-th state (and the last) suffices for it: a step of 1% of the
        shortest ``a/j``.
        """
        if traj.duration <= 0.0:
            t = np.array([0.0])
            return (t, *traj.evaluate(t), 1)
        lim = self.limits
        moving = np.any(np.asarray(traj.velocities) != 0.0, axis=0) | (
            np.ptp(np.asarray(traj.positions), axis=0) > 0.0)
        vel = np.asarray(lim.velocity, float)[moving]
        acc = np.asarray(lim.acceleration, float)[moving]
        jerk = np.asarray(lim.jerk, float)[moving]
        h_samples = float(np.max(np.diff(traj.times))) if len(traj.times) > 1 else traj.duration

        def step(rise: np.ndarray) -> float:
            rise = rise[np.isfinite(rise) & (rise > 0)]
            h = 0.01 * float(rise.min()) if len(rise) else h_samples
            return min(max(h, 2.5e-4), h_samples)

        def grid(h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
            n = max(2, int(math.ceil(traj.duration / h)) + 1)
            t = np.linspace(0.0, traj.duration, n)
            return (t, *traj.evaluate(t))

        h_acc = step(acc / jerk)
        t, q, qd, qdd = grid(h_acc)
        h = traj.duration / (len(t) - 1)
        peak = np.minimum(acc, _peak((qdd,), None, len(moving))[moving] + 0.5 * h * jerk)
        with np.errstate(divide="ignore"):
            h_vel = step(vel / peak)
        if h_vel < h:
            t, q, qd, qdd = grid(h_vel)
        stride = max(1, int(h_acc / (traj.duration / (len(t) - 1))))
        return t, q, qd, qdd, stride

    def _thin(self, t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # the states of (t, q) to collision-check: consecutive ones at most ``step`` apart
        if len(t) < 2:
            return t, q
        inc = np.max(np.abs(np.diff(q, axis=0)), axis=1)
        if np.any(inc > self.step):  # the bound did not hold: never thin across such a step
            return t, q
        keep, acc = [0], 0.0
        for i, d in enumerate(inc, start=1):
            if acc + d > self.step:
                keep.append(i - 1)
                acc = 0.0
            acc += d
        keep.append(len(t) - 1)
        idx = np.unique(keep)
        return t[idx], q[idx]

    def verify(self, traj: JointTrajectory, *, enforce_jerk: bool = True,
               derating: Derating | None = None, attempts: int = 1,
               certificate: Certificate | None = None) -> VerificationReport:
        """Check ``traj`` against every limit on a fine grid, and for collisions.

        ``certificate``: the certificate of the curve ``traj`` follows (its positions are
        that curve's points, whatever the timing): collisions are then its verdict and
        its certified clearance, proven between samples; without one, dense states are
        sampled (e.g. a trajectory that leaves the curve)."""
        derating = Derating() if derating is None else derating
        lim = self.limits
        lo, hi = np.asarray(lim.lower, float), np.asarray(lim.upper, float)
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        t, q, qd, qdd = traj.times, traj.positions, traj.velocities, traj.accelerations
        # a certificate proves collisions: then the grid need only resolve the limits
        tf, qf, qdf, qddf, stride = (self.fine_states(traj) if certificate is None
                                     else self.limit_states(traj))
        # the samples' efforts are this same inverse dynamics of these same states when
        # the trajectory was sampled with it (the planner's): the same numbers, kept
        tau = (traj.efforts if traj.effort_fn == self.dynamics.torques_batch
               else np.asarray(self.dynamics.torques_batch(q, qd, qdd), float))
        pick = np.arange(0, len(qf), stride)
        if pick[-1] != len(qf) - 1:
            pick = np.append(pick, len(qf) - 1)
        tau_dense = np.asarray(self.dynamics.torques_batch(qf[pick], qdf[pick], qddf[pick]),
                               float)
        jerk = (np.diff(qdd, axis=0) / np.diff(t)[:, None]) if len(t) > 1 \
            else np.zeros((0, q.shape[1]))
        dof = len(half)
        peaks = np.array([_peak((q, qf), mid, dof), _peak((qd, qdf), None, dof),
                          _peak((qdd, qddf), None, dof), _peak((jerk,), None, dof),
                          _peak((tau, tau_dense), None, dof)])
        limits = np.array([half, lim.velocity, lim.acceleration, lim.jerk, lim.effort],
                          float)
        ratios = dict(zip(QUANTITIES, _of_peaks(limits, peaks)))  # QUANTITIES' order
        enforced = QUANTITIES if enforce_jerk else tuple(k for k in QUANTITIES if k != "jerk")
        worst = {k: float(np.max(v)) for k, v in ratios.items()}
        # "not <=": a NaN ratio (a NaN effort of a 1e308 kg payload) is a violation too
        violations = tuple(k for k in enforced if not worst[k] <= 1.0 + TOLERANCE)
        # every value a number, enforced or not: a NaN jerk or time is no trajectory
        finite = bool(np.isfinite(peaks).all() and np.isfinite(t).all()
                      and math.isfinite(traj.duration))
        pairs: tuple[tuple[str, str], ...] = ()
        when, checked, max_step = None, 0, 0.0
        if certificate is not None:
            free = certificate.free
            if not free and certificate.failure is not None:
                pairs = (certificate.failure[2],)
            clearance, closest = certificate.certified_clearance, certificate.closest or ("", "")
            n_clear = 0
        else:  # thin the fine states to collision-check them
            td, qx = self._thin(tf, qf)
            checked = len(qx)
            max_step = float(np.abs(np.diff(qx, axis=0)).max()) if len(qx) > 1 else 0.0
            bad = self.world.first_invalid(qx)
            free = bad < 0
            if not free:
                when = float(td[bad])
                pairs = tuple(self.world.check(qx[bad]).pairs)
                clearance, closest = 0.0, (pairs[0] if pairs else ("", ""))
                n_clear = 1
            elif self.clearance_states > 0:
                idx = np.unique(np.linspace(0, len(qx) - 1, self.clearance_states).round()
                                .astype(int))
                clearance, closest = self.world.min_clearance(qx[idx])
                n_clear = len(idx)
            else:
                clearance, closest, n_clear = math.inf, ("", ""), 0
        return VerificationReport(
            ok=not violations and free and finite, joint_names=tuple(traj.joint_names),
            ratios={k: tuple(float(x) for x in v) for k, v in ratios.items()},
            worst=worst, enforced=tuple(enforced), violations=violations,
            collision_free=free, colliding_time=when, colliding_pairs=pairs,
            checked_states=checked, max_step=max_step, min_clearance=float(clearance),
            closest_pair=(closest[0], closest[1]), clearance_states=n_clear, derating=derating,
            attempts=attempts, certified=certificate is not None, finite=finite,
            rungs=None if certificate is None else asdict(certificate.rungs))


def derate(report: VerificationReport, current: Derating, *, margin: float = 0.98,
           floor: float = 0.05) -> Derating:
    """Tighter factors for each violated quantity: ``factor * margin / ratio``.

    Position and collision violations cannot be fixed by slowing down; callers raise.
    """
    f = current.to_dict()
    for k in report.violations:
        if k in f:
            r = report.worst[k]
            f[k] = max(floor, f[k] * margin / (r if math.isfinite(r) and r > 1 else 2.0))
    return Derating(**f)

