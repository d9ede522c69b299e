"""Planning from a moving state: the new motion blends into the one in progress.

A request may carry ``start_velocity`` [rad/s] and ``start_acceleration`` [rad/s^2]. The
trajectory then begins exactly in that state and reaches the goal at rest, without
stopping when the motions allow it, by superposition:

1. ``B``: the brake from (q0, v0, a0) to rest at q_r (:mod:`arduinobot.planner.timing.braking`), its
   acceleration and jerk scaled down until its torques fit the effort limits;
2. ``N``: the plan from rest at q_r to the goal, by the strategy
   :class:`FromMovingState` wraps (e.g. :class:`~arduinobot.planner.planning.from_rest.FromRest`);
3. ``q(t) = B(t) + N(t - s) - q_r``: the new motion starts ``s`` seconds into the
   brake. At ``t = 0`` it is (q0, v0, a0), at the end the goal at rest. The shift ``s``
   is the earliest of :data:`SHIFTS` (fractions of T_b) whose composed trajectory passes
   the verifier (every limit, and collisions on dense states: the sum leaves both
   checked paths). ``s = T_b`` is stop-and-go: the brake, then the plan.

Limits: the request's scaled limits, except where the moving state already exceeds
them (a joint moving faster than a slow request allows brakes within its own full
limits), for either profile. A start velocity or acceleration above its full limit is
refused naming the field, and so is a brake that cannot stop within the position limits.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from ruckig import Trajectory

from arduinobot.contract.errors import InvalidRequest, TrajectoryError
from arduinobot.planner.kinematics.limits import JointLimits
from arduinobot.planner.planning.context import PlanningContext
from arduinobot.planner.planning.motion import MotionRequest, MotionResult
from arduinobot.planner.planning.strategy import Strategy, at_rest, moves_at_start
from arduinobot.planner.timing.braking import EFFORT_MARGIN, brake_to_rest, effort_safe
from arduinobot.planner.timing.trajectory import JointTrajectory, Timing
from arduinobot.planner.timing.verify import Verifier

__all__ = ["FromMovingState", "BlendTiming", "SHIFTS", "rates"]

log = logging.getLogger(__name__)

SHIFTS = (0.0, 0.25, 0.5, 0.7, 0.8, 0.85, 0.9, 0.95, 1.0)  # fractions of the brake time


def rates(context: PlanningContext, values: Mapping[str, float] | None, field: str,
          bound: np.ndarray, what: str) -> np.ndarray:
    """A ``{joint: value}`` map of start velocities or accelerations as a vector in the
    context's joint order (missing joints 0), each within +-``bound``."""
    out = np.zeros(len(context.joint_names))
    if values is None:
        return out
    if not isinstance(values, Mapping):
        raise InvalidRequest("must map joint names to values", field=field)
    for name, v in values.items():
        f = f"{field}.{name}"
        if name not in context.joint_names:
            raise InvalidRequest(f"'{name}' is not an actuated joint "
                                 f"({', '.join(context.joint_names)})", field=f)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InvalidRequest(f"{v!r} is not a finite number", field=f)
        i = context.joint_names.index(name)
        if abs(v) > bound[i] * (1 + 1e-9):
            raise InvalidRequest(f"{v:.6g} exceeds the {what} limit {bound[i]:.6g}", field=f,
                                 details={"joint": name, "limit": float(bound[i])})
        out[i] = float(v)
    return out


class BlendTiming:
    """``q(t) = B(t) + N(t - shift) - q_r`` (see the module doc): ``evaluate(ts)`` gives
    (q, qd, qdd), each shape (m, dof); times clamped to [0, duration]."""

    def __init__(self, brake: Trajectory, rest: np.ndarray, new: Timing,
                 shift: float) -> None:
        self.brake, self.rest, self.new, self.shift = brake, rest, new, float(shift)
        self.brake_duration = float(brake.duration)
        self.duration = max(self.brake_duration, self.shift + new.duration)
        self.dof = len(rest)
        self.goal = new.goal

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ts = np.clip(np.atleast_1d(np.asarray(ts, float)), 0.0, self.duration)
        bq = np.empty((len(ts), self.dof))
        bqd = np.zeros_like(bq)
        bqdd = np.zeros_like(bq)
        for k, t in enumerate(ts):
            if t >= self.brake_duration:
                bq[k] = self.rest
            else:
                bq[k], bqd[k], bqdd[k] = self.brake.at_time(float(t))
        nq, nqd, nqdd = self.new.evaluate(ts - self.shift)  # clamped: rest at q_r before
        q = bq + nq - self.rest
        end = ts >= self.duration
        q[end] = self.goal
        qd, qdd = bqd + nqd, bqdd + nqdd
        qd[end] = 0.0
        qdd[end] = 0.0
        return q, qd, qdd


def _effort_safe_brake(context: PlanningContext, q0: np.ndarray, v0: np.ndarray,
                       a0: np.ndarray, lim: JointLimits, request: MotionRequest
                       ) -> Trajectory:
    """The brake with the largest acceleration and jerk scale (never below the
    acceleration the arm already has) whose torques fit the effort limits
    (:func:`arduinobot.planner.timing.braking.effort_safe`), with what the arm carries."""
    world = context.world(request.obstacles, request.attached, request.clouds,
                          ground=request.ground,
                                     allowed=request.allowed)
    dynamics = context.payload(world.attached)[0]
    tr, ratio = effort_safe(
        lambda f: brake_to_rest(q0, v0, a0, velocity=lim.velocity,
                                acceleration=np.maximum(f * lim.acceleration, np.abs(a0)),
                                jerk=f * lim.jerk),
        dynamics.torques_batch, lim.effort, tries=30)
    if ratio > EFFORT_MARGIN:
        raise TrajectoryError("no brake from the moving start within the effort limits",
                              details={"stage": "brake", "effort_ratio": ratio})
    return tr



@dataclass(frozen=True)
class _Brake:
    """The brake from the moving start ``q0`` [rad] to rest at ``rest`` [rad] (each
    shape (dof,)), and the limits it and the blend keep."""

    q0: np.ndarray
    trajectory: Trajectory
    rest: np.ndarray
    limits: JointLimits


def _moving_limits(context: PlanningContext, request: MotionRequest, v0: np.ndarray,
                   a0: np.ndarray) -> JointLimits:
    """The request's scaled limits, raised where the moving state already exceeds them:
    a joint moving faster than a slow request allows brakes within its own full limits."""
    scaled = context.limits(*context.scaling(request))
    full = context.limits(1.0, 1.0)
    return replace(scaled, velocity=np.maximum(scaled.velocity, np.abs(v0)),
                   acceleration=np.maximum(scaled.acceleration, np.abs(a0)),
                   jerk=np.maximum(scaled.jerk, np.where(np.abs(a0) > scaled.acceleration,
                                                         full.jerk, scaled.jerk)))


def _brake(context: PlanningContext, request: MotionRequest, q0: np.ndarray,
           v0: np.ndarray, a0: np.ndarray) -> _Brake:
    """The effort-safe brake from (q0, v0, a0), refused if it cannot stop within the
    position limits (InvalidRequest naming the joint's start velocity)."""
    lim = _moving_limits(context, request, v0, a0)
    brake = _effort_safe_brake(context, q0, v0, a0, lim, request)
    ext = brake.position_extrema
    lo, hi = np.array([e.min for e in ext]), np.array([e.max for e in ext])
    if np.any(lo < lim.lower - 1e-9) or np.any(hi > lim.upper + 1e-9):
        j = int(np.argmax(np.maximum(lim.lower - lo, hi - lim.upper)))
        name = context.joint_names[j]
        raise InvalidRequest(f"from this velocity {name} cannot stop within its position "
                             "limits", field=f"start_velocity.{name}",
                             details={"joint": name,
                                      "brake_range": [float(lo[j]), float(hi[j])]})
    rest = np.array(brake.at_time(float(brake.duration))[0], float)
    return _Brake(q0, brake, np.clip(rest, lim.lower, lim.upper), lim)


def _blend(context: PlanningContext, request: MotionRequest, brake: _Brake,
           plan: MotionResult, t0: float) -> MotionResult:
    """The brake and ``plan`` (from rest at ``brake.rest``) superposed at the earliest
    shift of :data:`SHIFTS` whose trajectory passes the verifier."""
    new = plan.trajectory.timing
    world = context.world(request.obstacles, request.attached, request.clouds,
                          ground=request.ground,
                                     allowed=request.allowed)
    dynamics, profiles = context.payload(world.attached)  # with what it carries
    verifier = Verifier(brake.limits, dynamics, world,
                        clearance_states=context.clearance_states)
    enforce_jerk = profiles[request.profile].enforce_jerk
    duration = float(brake.trajectory.duration)
    t1 = time.perf_counter()
    report = None
    for frac in SHIFTS:
        timing = BlendTiming(brake.trajectory, brake.rest, new, frac * duration)
        traj = JointTrajectory.sample(timing, dynamics.torques_batch,
                                      joint_names=context.joint_names,
                                      sample_rate=request.sample_rate,
                                      profile=request.profile,
                                      max_samples=request.max_samples)
        report = verifier.verify(traj, enforce_jerk=enforce_jerk)
        if report.ok:
            timing_s = {**plan.timing, "blend": time.perf_counter() - t1,
                        "total": time.perf_counter() - t0}
            log.info("moving start: brake %.3f s, plan %.3f s, blended at %.0f%% of the "
                     "brake: %.3f s", duration, new.duration, 100 * frac, traj.duration)
            return MotionResult(trajectory=traj, path=np.vstack([brake.q0, plan.path]),
                                timing=timing_s, verification=report, planner=plan.planner)
    raise TrajectoryError("no blend from the moving start passed verification, not even "
                          "braking to rest first", details={
                              "stage": "blend", "report": report.to_dict() if report else None})


class FromMovingState:
    """A moving start blended into the motion ``inner`` plans from rest (see the module
    doc): ``inner`` is called once, for the plan from where the brake comes to rest, and
    nothing here calls back into :class:`arduinobot.planner.planning.pipeline.MotionPlanner`."""

    def __init__(self, inner: Strategy) -> None:
        self.inner = inner
        self.name = f"{inner.name}, from a moving state"

    def accepts(self, request: MotionRequest) -> bool:
        return moves_at_start(request) and self.inner.accepts(at_rest(request))

    def solve(self, context: PlanningContext, request: MotionRequest) -> MotionResult:
        """Plan ``request`` from its moving start.

        Raises:
            InvalidRequest: a start velocity/acceleration beyond the full limits, or a
                brake that cannot stop within the position limits; and whatever
                ``inner`` raises.
            TrajectoryError: no shift passed verification (not even stop-and-go: the
                brake itself collides or breaks a limit).
        """
        t0 = time.perf_counter()
        q0 = context.validate(request)
        full = context.limits(1.0, 1.0)
        v0 = rates(context, request.start_velocity, "start_velocity", full.velocity,
                   "velocity")
        a0 = rates(context, request.start_acceleration, "start_acceleration",
                   full.acceleration, "acceleration")
        if not (v0.any() or a0.any()):  # at rest after all: the plan from rest
            return self.inner.solve(context, at_rest(request))
        brake = _brake(context, request, q0, v0, a0)
        rest = dict(zip(context.joint_names, brake.rest.tolist()))
        plan = self.inner.solve(context, replace(at_rest(request), start=rest))
        return _blend(context, request, brake, plan, t0)
