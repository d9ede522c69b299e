"""Plan requests and responses on the wire <-> :mod:`planner.pipeline`.

Shared by the service's workers and ``arduinobot plan --local [--request FILE]``, so a
request is parsed, refused and answered the same way in both.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from description import Description
from planner.errors import PlanningError
from planner.goals import JointGoal, NamedGoal, PositionGoal
from planner.pipeline import MotionRequest

from .requests import joint_values, obstacles
from .wire import check_finite


def goal(description: Description, data: Mapping[str, Any]) -> JointGoal | NamedGoal | PositionGoal:
    """The goal of a plan request (exactly one of joints, named, position)."""
    if "joints" in data:
        return JointGoal(joint_values(description, data["joints"], field="goal.joints",
                                      fill=False))
    if "named" in data:
        return NamedGoal(data["named"])  # looked up in the request's group by the planner
    return PositionGoal(tuple(float(v) for v in data["position"]))  # type: ignore[arg-type]


def plan_request(description: Description, data: Mapping[str, Any]) -> MotionRequest:
    """A validated v1 plan request (see ``service/schema/plan_request.json``) as a
    :class:`planner.pipeline.MotionRequest`. A missing start is all actuated joints at 0."""
    opts = {k: data[k] for k in ("group", "planner", "planning_time", "velocity_scaling",
                                 "acceleration_scaling", "profile", "sample_rate", "seed",
                                 "start_velocity", "start_acceleration")
            if k in data}
    for k in ("planning_time", "velocity_scaling", "acceleration_scaling", "sample_rate"):
        if k in opts:
            opts[k] = float(opts[k])
    return MotionRequest(
        goal=goal(description, data["goal"]),
        start=joint_values(description, data.get("start"), field="start"),
        obstacles=obstacles(description, data.get("obstacles")),
        **opts)


def plan_response(result: Any) -> dict[str, Any]:
    """A :class:`planner.pipeline.MotionResult` as the v1 response (without request_id):
    trajectory (actuated joints), duration [s], path (waypoints in joint_names order),
    timing (seconds per stage), verification, planner."""
    traj = result.trajectory
    arrays = {"positions": traj.positions, "velocities": traj.velocities,
              "accelerations": traj.accelerations, "effort": traj.efforts,
              "time_from_start": traj.times, "path": result.path}
    for name, a in arrays.items():
        if not np.isfinite(np.asarray(a, float)).all():
            raise PlanningError(f"the planner returned non-finite {name}")
    # from the sample arrays (m, dof): much faster than per-point objects
    columns = zip(traj.positions.tolist(), traj.velocities.tolist(),
                  traj.accelerations.tolist(), traj.efforts.tolist(), traj.times.tolist())
    points = [{"positions": q, "velocities": qd, "accelerations": qdd, "effort": tau,
               "time_from_start": t} for q, qd, qdd, tau, t in columns]
    body = {
        "trajectory": {"joint_names": list(traj.joint_names), "points": points},
        "duration": float(traj.duration),
        "path": np.asarray(result.path, float).tolist(),
        "timing": {str(k): float(v) for k, v in dict(result.timing).items()},
        "verification": result.verification.to_dict(),
        "planner": str(result.planner),
    }
    check_finite({k: body[k] for k in ("duration", "timing", "verification")})
    return body  # every number finite: wire.encode(..., finite=True) may take it
