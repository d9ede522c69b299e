"""Stopping a moving arm within every limit, and ruckig motions that fit the effort.

Each takes the robot's full limits and, optionally, its inverse dynamics
(``torques(qs, qds, qdds)``, each (m, dof) -> (m, dof) [N m]).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Literal

import numpy as np
from ruckig import Trajectory

from arduinobot.execution.ruckig_segments import PathStop, RestOf, RuckigSegment, stop_segment
from arduinobot.execution.segments import Segment
from arduinobot.planner.kinematics.limits import JointLimits
from arduinobot.planner.timing import braking
from arduinobot.planner.timing.braking import TorqueFn

log = logging.getLogger(__name__)

StopKind = Literal["path", "joint", "finish"]


def choose_stop(seg: Segment, s: float, cur: tuple[np.ndarray, np.ndarray, np.ndarray], *,
                limits: JointLimits, torques: TorqueFn | None
                ) -> tuple[StopKind, Segment]:
    """How to stop ``seg`` played up to its time ``s`` [s], at commanded ``cur``.

    1. ``path``: brake along the segment's own path (it stays on the collision-checked
       path), the hardest braking tried (path-time deceleration 8, 5.6, 3.9, ...
       [1/s^2]) whose motion keeps every velocity, acceleration, jerk and effort limit
       (checked on 1 ms samples).
    2. ``finish``: when braking on the path needs more path than is left, the rest of
       the segment is the stop (it ends at rest, within every limit).
    3. ``joint``: ruckig's per-joint time-optimal stop (effort-safe), if it stays within
       the position limits.
    4. ``finish`` otherwise.
    """
    dec = 8.0
    for _ in range(10):
        ps = PathStop(seg, s, dec, dec / 0.05)
        if ps.passes_end:
            return "finish", RestOf(seg, s)
        if within_limits(ps, limits, torques):
            return "path", ps
        dec *= 0.7
    q, qd, qdd = cur
    js = effort_safe(lambda f: stop_segment(
        seg.joint_names, q, qd, qdd, velocity=limits.velocity,
        acceleration=np.maximum(f * limits.acceleration, np.abs(qdd)), jerk=f * limits.jerk),
        limits, torques)
    lo, hi = js.position_extrema()
    if np.all(lo >= limits.lower - 1e-9) and np.all(hi <= limits.upper + 1e-9):
        return "joint", js
    log.warning("no stop within the limits leaves the path early: finishing the motion")
    return "finish", RestOf(seg, s)


def within_limits(seg: Segment, lim: JointLimits, torques: TorqueFn | None, *,
                  step: float = 1e-3) -> bool:
    """Whether ``seg`` keeps positions, velocities, accelerations, jerks (finite
    differences) and, given the inverse dynamics, efforts within the limits ``lim`` on
    ``step`` [s] samples."""
    ts = np.linspace(0.0, seg.duration, max(3, int(math.ceil(seg.duration / step)) + 1))
    q, qd, qdd = (np.array(x) for x in zip(*(seg.evaluate(t) for t in ts)))
    h = ts[1] - ts[0]
    tol = 1 + 1e-6
    ok = bool(np.all(q >= lim.lower - 1e-9) and np.all(q <= lim.upper + 1e-9)
              and np.all(np.abs(qd) <= lim.velocity * tol)
              and np.all(np.abs(qdd) <= lim.acceleration * tol)
              and np.all(np.abs(np.diff(qdd, axis=0)) <= lim.jerk * h * tol))
    if ok and torques is not None:
        ok = bool(np.all(np.abs(np.asarray(torques(q, qd, qdd))) <= lim.effort * tol))
    return ok


def effort_safe(make: Callable[[float], RuckigSegment], limits: JointLimits,
                torques: TorqueFn | None) -> RuckigSegment:
    """``make(scale)`` with the largest scale in (0, 1] (tried as 1, 0.8, 0.64, ...)
    whose motion keeps every joint's torque within 95% of its effort limit
    (:func:`arduinobot.planner.timing.braking.effort_safe`). ``scale`` multiplies acceleration and jerk.
    A robot must stop anyway: if none fits, the last is used, with a warning."""
    if torques is None:
        return make(1.0)
    made: list[RuckigSegment] = []

    def trajectory(scale: float) -> Trajectory:
        made.append(make(scale))
        return made[-1].trajectory

    _, ratio = braking.effort_safe(trajectory, torques, limits.effort)
    if ratio > braking.EFFORT_MARGIN:
        log.warning("no ruckig motion within the effort limits (%.0f%% at the gentlest "
                    "scale tried)", 100 * ratio)
    return made[-1]
