"""Planning from a moving state: the new motion blends into the one in progress.

A request may carry ``start_velocity`` [rad/s] and ``start_acceleration`` [rad/s^2]. The
trajectory then begins exactly in that state and reaches the goal at rest, without
stopping when the motions allow it, by superposition:

1. ``B``: the brake from (q0, v0, a0) to rest at q_r (:mod:`planner.timing.braking`), its
   acceleration and jerk scaled down until its torques fit the effort limits;
2. ``N``: the ordinary plan from rest at q_r to the goal (collision-free path, timing);
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
from dataclasses import replace
from typing import Any, Protocol

import numpy as np
from ruckig import Trajectory

from ..errors import InvalidRequest, TrajectoryError
from ..kinematics.limits import JointLimits
from ..timing.braking import EFFORT_MARGIN, brake_to_rest, effort_safe
from ..timing.trajectory import CurveTiming, JointTrajectory
from ..timing.verify import Verifier
from .motion import MotionRequest, MotionResult


class MotionPlanner(Protocol):
    """What a moving start needs of :class:`planner.planning.pipeline.MotionPlanner` (named by
    its interface so this module, above the pipeline, does not import it)."""

    joint_names: tuple[str, ...]
    dynamics: Any
    clearance_states: int

    def world(self, obstacles: tuple[Any, ...]) -> Any: ...
    def limits(self, velocity_scaling: float, acceleration_scaling: float) -> JointLimits: ...
    def scaling(self, request: MotionRequest) -> tuple[float, float]: ...
    def validate(self, req: MotionRequest) -> np.ndarray: ...
    def solve(self, request: MotionRequest) -> MotionResult: ...


log = logging.getLogger(__name__)

SHIFTS = (0.0, 0.25, 0.5, 0.7, 0.8, 0.85, 0.9, 0.95, 1.0)  # fractions of the brake time


def rates(planner: MotionPlanner, values: Mapping[str, float] | None, field: str,
          bound: np.ndarray, what: str) -> np.ndarray:
    """A ``{joint: value}`` map of start velocities or accelerations as a vector in the
    planner's joint order (missing joints 0), each within +-``bound``."""
    out = np.zeros(len(planner.joint_names))
    if values is None:
        return out
    if not isinstance(values, Mapping):
        raise InvalidRequest("must map joint names to values", field=field)
    for name, v in values.items():
        f = f"{field}.{name}"
        if name not in planner.joint_names:
            raise InvalidRequest(f"'{name}' is not an actuated joint "
                                 f"({', '.join(planner.joint_names)})", field=f)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InvalidRequest(f"{v!r} is not a finite number", field=f)
        i = planner.joint_names.index(name)
        if abs(v) > bound[i] * (1 + 1e-9):
            raise InvalidRequest(f"{v:.6g} exceeds the {what} limit {bound[i]:.6g}", field=f,
                                 details={"joint": name, "limit": float(bound[i])})
        out[i] = float(v)
    return out


class BlendTiming:
    """``q(t) = B(t) + N(t - shift) - q_r`` (see the module doc): ``evaluate(ts)`` gives
    (q, qd, qdd), each shape (m, dof); times clamped to [0, duration]."""

    def __init__(self, brake: Trajectory, rest: np.ndarray, new: CurveTiming,
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


def _effort_safe_brake(planner: MotionPlanner, q0: np.ndarray, v0: np.ndarray,
                       a0: np.ndarray, lim: JointLimits) -> Trajectory:
    """The brake with the largest acceleration and jerk scale (never below the
    acceleration the arm already has) whose torques fit the effort limits
    (:func:`planner.timing.braking.effort_safe`)."""
    tr, ratio = effort_safe(
        lambda f: brake_to_rest(q0, v0, a0, velocity=lim.velocity,
                                acceleration=np.maximum(f * lim.acceleration, np.abs(a0)),
                                jerk=f * lim.jerk),
        planner.dynamics.torques_batch, lim.effort, tries=30)
    if ratio > EFFORT_MARGIN:
        raise TrajectoryError("no brake from the moving start within the effort limits",
                              details={"stage": "brake", "effort_ratio": ratio})
    return tr


def solve_moving(planner: MotionPlanner, request: MotionRequest) -> MotionResult:
    """Plan ``request`` from its moving start (see the module doc).

    Raises:
        InvalidRequest: a start velocity/acceleration beyond the full limits, or a brake
            that cannot stop within the position limits; and whatever ``solve`` raises.
        TrajectoryError: no shift passed verification (not even stop-and-go: the brake
            itself collides or breaks a limit).
    """
    t0 = time.perf_counter()
    q0 = planner.validate(request)
    full = planner.limits(1.0, 1.0)
    v0 = rates(planner, request.start_velocity, "start_velocity", full.velocity, "velocity")
    a0 = rates(planner, request.start_acceleration, "start_acceleration",
               full.acceleration, "acceleration")
    if not (v0.any() or a0.any()):  # at rest after all: the ordinary plan
        return planner.solve(replace(request, start_velocity=None, start_acceleration=None))
    scaled = planner.limits(*planner.scaling(request))
    # the moving state may already exceed a slow request's limits: brake within its own
    lim = replace(scaled, velocity=np.maximum(scaled.velocity, np.abs(v0)),
                  acceleration=np.maximum(scaled.acceleration, np.abs(a0)),
                  jerk=np.maximum(scaled.jerk, np.where(np.abs(a0) > scaled.acceleration,
                                                        full.jerk, scaled.jerk)))
    brake = _effort_safe_brake(planner, q0, v0, a0, lim)
    ext = brake.position_extrema
    lo, hi = np.array([e.min for e in ext]), np.array([e.max for e in ext])
    if np.any(lo < lim.lower - 1e-9) or np.any(hi > lim.upper + 1e-9):
        j = int(np.argmax(np.maximum(lim.lower - lo, hi - lim.upper)))
        raise InvalidRequest(f"from this velocity {planner.joint_names[j]} cannot stop within "
                             "its position limits", field=f"start_velocity."
                             f"{planner.joint_names[j]}",
                             details={"joint": planner.joint_names[j],
                                      "brake_range": [float(lo[j]), float(hi[j])]})
    rest = np.array(brake.at_time(float(brake.duration))[0], float)
    rest = np.clip(rest, lim.lower, lim.upper)
    plan = planner.solve(replace(request, start=dict(zip(planner.joint_names, rest.tolist())),
                                 start_velocity=None, start_acceleration=None))
    new = plan.trajectory.timing
    world = planner.world(request.obstacles)
    verifier = Verifier(lim, planner.dynamics, world,
                        clearance_states=planner.clearance_states)
    t1 = time.perf_counter()
    report = None
    for frac in SHIFTS:
        timing = BlendTiming(brake, rest, new, frac * float(brake.duration))
        traj = JointTrajectory.sample(timing, planner.dynamics.torques_batch,
                                      joint_names=planner.joint_names,
                                      sample_rate=request.sample_rate,
                                      profile=request.profile,
                                      max_samples=request.max_samples)
        report = verifier.verify(traj, enforce_jerk=request.profile == "jerk_limited")
        if report.ok:
            timing_s = {**plan.timing, "blend": time.perf_counter() - t1,
                        "total": time.perf_counter() - t0}
            log.info("moving start: brake %.3f s, plan %.3f s, blended at %.0f%% of the "
                     "brake: %.3f s", brake.duration, new.duration, 100 * frac,
                     traj.duration)
            return MotionResult(trajectory=traj, path=np.vstack([q0, plan.path]),
                                timing=timing_s, verification=report, planner=plan.planner)
    raise TrajectoryError("no blend from the moving start passed verification, not even "
                          "braking to rest first", details={
                              "stage": "blend", "report": report.to_dict() if report else None})
