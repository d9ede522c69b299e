"""Timed trajectories: a curve followed by a path-parameter profile, sampled for motors.

Both time parameterisations (toppra, ruckig) produce the same thing: for each smooth
section of the :class:`~arduinobot.planner.timing.curve.Curve`, a scalar profile ``s(t)`` of the path
parameter. Joint states follow exactly from the chain rule::

    q = c(s),   qd = c'(s) sd,   qdd = c'(s) sdd + c''(s) sd^2

so every position lies on the collision-checked curve, at any time, not only at samples.
:class:`JointTrajectory` is the JointTrajectory-shaped result (ROS ``trajectory_msgs``):
samples at a fixed rate plus the exact final state, JSON/CSV export, and ``at(t)``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Protocol

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.ranges import check_range
from arduinobot.contract.samples import samples_csv

if TYPE_CHECKING:  # toppra, ~1 s to import: only where a curve is timed
    from arduinobot.planner.timing.curve import PathCurve
    from arduinobot.planner.timing.curve_eval import Packed

# Inverse dynamics on a batch: (qs, qds, qdds), each (m, dof) -> torques (m, dof) [N m].
TorqueFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


class ScalarProfile(Protocol):
    """A path-parameter profile on [0, duration]: ``evaluate(ts) -> (s, sd, sdd)``, each (m,)."""

    @property
    def duration(self) -> float: ...

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


class Timing(Protocol):
    """What a :class:`JointTrajectory` samples: joint states on [0, duration] [s].

    ``evaluate(ts)`` gives (q, qd, qdd), each shape (m, dof), times clamped to [0,
    duration]; ``goal`` [rad], shape (dof,), is the exact final position. A
    :class:`CurveTiming` is one; so is any strategy's own timing (a moving start's blend).
    """

    @property
    def duration(self) -> float: ...

    @property
    def goal(self) -> np.ndarray: ...

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


class RestProfile:
    """The profile of a path that does not move: zero duration."""

    duration = 0.0

    def polynomial(self) -> tuple[np.ndarray, np.ndarray, float, float]:
        """As :meth:`RuckigProfile.polynomial <arduinobot.planner.timing.ruckig_timing.RuckigProfile.
        polynomial>`: one phase at rest, at s = 0."""
        return np.zeros(1), np.zeros((1, 4)), 0.0, 0.0

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        z = np.zeros(len(np.atleast_1d(ts)))
        return z, z.copy(), z.copy()


class CurveTiming:
    """Sections of a curve, each with its own profile, played one after the other.

    Every section starts and ends at rest. ``evaluate(ts)`` gives (q, qd, qdd), each
    shape (m, dof); times outside [0, duration] are clamped.
    """

    def __init__(self, sections: Sequence[tuple[PathCurve, ScalarProfile]], *,
                 goal: np.ndarray | None = None) -> None:
        if not sections:
            raise InvalidRequest("a timing needs at least one section", field="sections")
        self.sections = tuple(sections)
        durs = np.array([p.duration for _, p in self.sections], float)
        self.t0 = np.concatenate(([0.0], np.cumsum(durs)[:-1]))
        self.duration = float(durs.sum())
        self.dof = self.sections[0][0].dof
        self.goal = self.sections[-1][0].end if goal is None else np.asarray(goal, float)
        # the compiled evaluator's arrays, made at the first evaluate
        self._packed: Packed | None = None

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._packed is None:
            found = (getattr(p, "polynomial", None) for _, p in self.sections)
            polys = [f for f in found if f is not None]
            if len(polys) == len(self.sections):
                # piecewise-cubic profiles (ruckig's, a rest): one compiled pass a state
                from arduinobot.planner.timing.curve_eval import pack
                self._packed = pack(self.t0, [(c, f()) for (c, _), f in
                                              zip(self.sections, polys)],
                                    self.goal, self.duration)
        if self._packed is not None:
            from arduinobot.planner.timing.curve_eval import states
            return states(self._packed, ts)
        return self.evaluate_numpy(ts)

    def evaluate_numpy(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`evaluate` in numpy for any profile (the compiled pass's reference)."""
        ts = np.clip(np.atleast_1d(np.asarray(ts, float)), 0.0, self.duration)
        k = np.clip(np.searchsorted(self.t0, ts, side="right") - 1, 0, len(self.sections) - 1)
        q = np.empty((len(ts), self.dof))
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        for i, (curve, prof) in enumerate(self.sections):
            m = k == i
            if not m.any():
                continue
            s, sd, sdd = prof.evaluate(ts[m] - self.t0[i])
            q[m], d1, d2 = curve.jet(*curve.locate(s), (0, 1, 2))
            qd[m] = d1 * sd[:, None]
            qdd[m] = d1 * sdd[:, None] + d2 * (sd * sd)[:, None]
        # The final state is exact: the goal, at rest (not the curve formula's rounding).
        end = ts >= self.duration
        q[end] = self.goal
        qd[end] = 0.0
        qdd[end] = 0.0
        return q, qd, qdd


@dataclass(frozen=True)
class TrajectoryPoint:
    """One sample: per joint positions [rad], velocities [rad/s], accelerations [rad/s^2],
    effort [N m] (inverse dynamics), at ``time_from_start`` [s]."""

    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    accelerations: tuple[float, ...]
    effort: tuple[float, ...]
    time_from_start: float

    @classmethod
    def of(cls, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray,
           t: float) -> TrajectoryPoint:
        """From one state's arrays, each shape (dof,)."""
        return cls(tuple(map(float, q)), tuple(map(float, qd)), tuple(map(float, qdd)),
                   tuple(map(float, tau)), float(t))

    def to_dict(self) -> dict[str, object]:
        return {"positions": list(self.positions), "velocities": list(self.velocities),
                "accelerations": list(self.accelerations), "effort": list(self.effort),
                "time_from_start": self.time_from_start}


def check_sample_count(samples: int, *, duration: float, sample_rate: float, limit: int,
                       cap: str | None = None) -> None:
    """Refuse ``samples`` (of a ``duration`` [s] motion at ``sample_rate`` [Hz]) above
    ``limit``: InvalidRequest on ``sample_rate`` naming the limit (``cap``: its name, if
    it has one) and the largest rate that fits (``details.max_sample_rate`` [Hz], 0 if
    none of at least 1 Hz does)."""
    if samples <= limit:
        return
    fits = (limit - 2) / duration if duration > 0 else float(limit)
    fits = float(int(fits)) if fits >= 1.0 else 0.0
    hint = (f"ask for at most {fits:g} Hz" if fits >= 1.0 else
            "no sample rate of at least 1 Hz fits: raise the scalings")
    named = f" ({cap})" if cap else ""
    details: dict[str, object] = {"limit": limit, "samples": samples, "duration": duration,
                                  "sample_rate": sample_rate, "max_sample_rate": fits}
    if cap:
        details["cap"] = cap
    raise InvalidRequest(
        f"{sample_rate:g} Hz over this {duration:.4g} s motion gives {samples} samples, "
        f"more than the {limit} allowed{named}: {hint}", field="sample_rate", details=details)


def sample_times(duration: float, rate: float, *, max_samples: int | None = None
                 ) -> np.ndarray:
    """Times [s] at ``rate`` [Hz] from 0, always ending with exactly ``duration``.

    Raises:
        InvalidRequest: (field ``sample_rate``) a rate outside ``RANGES["sample_rate"]``
            ([1, 1000] Hz), or more than ``max_samples`` samples, decided before any is
            made (:func:`check_sample_count`).
    """
    rate = check_range(rate, "sample_rate")
    n = int(math.floor(duration * rate + 1e-9))
    if max_samples is not None:
        check_sample_count(n + 2, duration=duration, sample_rate=rate, limit=max_samples)
    ts = np.arange(n + 1) / rate
    if duration - ts[-1] > 1e-9:
        ts = np.append(ts, duration)
    else:
        ts[-1] = duration
    return ts


@dataclass(frozen=True)
class JointTrajectory:
    """A sampled, timed trajectory of the actuated joints.

    Attributes:
        joint_names: the actuated joints, in column order.
        times: sample times [s], shape (m,), the last one is ``duration``.
        positions, velocities, accelerations, efforts: shape (m, dof).
        duration: the exact duration [s].
        sample_rate: [Hz].
        profile: 'jerk_limited' or 'time_optimal'.
    """

    joint_names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    efforts: np.ndarray
    duration: float
    sample_rate: float
    profile: str
    timing: Timing = field(repr=False, compare=False)
    effort_fn: TorqueFn = field(repr=False, compare=False)

    @classmethod
    def sample(cls, timing: Timing, effort_fn: TorqueFn, *,
               joint_names: Sequence[str], sample_rate: float = 100.0,
               profile: str = "jerk_limited", max_samples: int | None = None
               ) -> JointTrajectory:
        """Sample ``timing`` at ``sample_rate`` [Hz] (in ``RANGES``) plus its exact final state;
        more than ``max_samples`` samples is refused first (see :func:`sample_times`)."""
        ts = sample_times(timing.duration, sample_rate, max_samples=max_samples)
        q, qd, qdd = timing.evaluate(ts)
        tau = np.asarray(effort_fn(q, qd, qdd), float)
        for a in (ts, q, qd, qdd, tau):
            a.setflags(write=False)
        return cls(tuple(joint_names), ts, q, qd, qdd, tau, timing.duration,
                   float(sample_rate), profile, timing, effort_fn)

    @cached_property
    def points(self) -> tuple[TrajectoryPoint, ...]:
        return tuple(map(TrajectoryPoint.of, self.positions, self.velocities,
                         self.accelerations, self.efforts, self.times))

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd) at any times [s], each (m, dof); clamped to [0, duration]."""
        return self.timing.evaluate(ts)

    def at(self, t: float) -> TrajectoryPoint:
        """The exact state at time ``t`` [s] (clamped to [0, duration])."""
        if not math.isfinite(t):
            raise InvalidRequest(f"{t!r} is not a finite time", field="t")
        q, qd, qdd = self.timing.evaluate(np.array([t]))
        tau = np.asarray(self.effort_fn(q, qd, qdd), float)
        return TrajectoryPoint.of(q[0], qd[0], qdd[0], tau[0], min(max(t, 0.0), self.duration))

    def to_dict(self) -> dict[str, object]:
        return {"joint_names": list(self.joint_names), "duration": self.duration,
                "sample_rate": self.sample_rate, "profile": self.profile,
                "points": [p.to_dict() for p in self.points]}

    def to_json(self) -> str:
        """trajectory_msgs/JointTrajectory-shaped JSON (time_from_start in seconds)."""
        return json.dumps(self.to_dict())

    def to_csv(self) -> str:
        """One row per sample (:func:`samples_csv`)."""
        return samples_csv(self.joint_names, self.times, self.positions, self.velocities,
                           self.accelerations, self.efforts)

