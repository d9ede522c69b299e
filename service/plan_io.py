"""Plan requests and responses on the wire <-> :mod:`planner.pipeline`.

Shared by the service's workers and ``arduinobot plan --local [--request FILE]``, so a
request is parsed, refused and answered the same way in both.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from description import Description
from planner.errors import InvalidRequest
from planner.goals import JointGoal, NamedGoal, PositionGoal
from planner.pipeline import MotionRequest

from .requests import joint_values, obstacles


def goal(description: Description, data: Mapping[str, Any]) -> JointGoal | NamedGoal | PositionGoal:
    """The goal of a plan request (exactly one of joints, named, position)."""
    if "joints" in data:
        return JointGoal(joint_values(description, data["joints"], field="goal.joints",
                                      fill=False))
    if "named" in data:
        name = data["named"]
        states = description.srdf.group_states if description.srdf is not None else {}
        if name not in states:
            raise InvalidRequest(f"no named state '{name}'; known: {', '.join(states)}",
                                 field="goal.named", details={"known": list(states)})
        return NamedGoal(name)
    return PositionGoal(tuple(float(v) for v in data["position"]))  # type: ignore[arg-type]


def plan_request(description: Description, data: Mapping[str, Any]) -> MotionRequest:
    """A validated v1 plan request (see ``service/schema/plan_request.json``) as a
    :class:`planner.pipeline.MotionRequest`. A missing start is all actuated joints at 0."""
    opts = {k: data[k] for k in ("group", "planner", "planning_time", "velocity_scaling",
                                 "acceleration_scaling", "profile", "sample_rate", "seed")
            if k in data}
    for k in ("planning_time", "velocity_scaling", "acceleration_scaling", "sample_rate"):
        if k in opts:
            opts[k] = float(opts[k])
    return MotionRequest(
        goal=goal(description, data["goal"]),
        start=joint_values(description, data.get("start"), field="start"),
        obstacles=obstacles(description, data.get("obstacles")),
        **opts)


def _floats(v: Any) -> list[float]:
    return [float(x) for x in v]


def plan_response(result: Any) -> dict[str, Any]:
    """A :class:`planner.pipeline.MotionResult` as the v1 response (without request_id):
    trajectory (actuated joints), duration [s], path (waypoints in joint_names order),
    timing (seconds per stage), verification, planner."""
    traj = result.trajectory
    points = [{"positions": _floats(p.positions), "velocities": _floats(p.velocities),
               "accelerations": _floats(p.accelerations), "effort": _floats(p.effort),
               "time_from_start": float(p.time_from_start)} for p in traj.points]
    return {
        "trajectory": {"joint_names": list(traj.joint_names), "points": points},
        "duration": float(traj.duration),
        "path": [_floats(w) for w in result.path],
        "timing": {str(k): float(v) for k, v in dict(result.timing).items()},
        "verification": result.verification.to_dict(),
        "planner": str(result.planner),
    }
