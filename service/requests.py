"""Check the robot-dependent parts of validated wire requests: joint states, obstacles.

Shared by the service's workers and the ``--local`` commands, so both refuse alike.
Input has passed :func:`service.wire.decode` (types, ranges, finiteness);
this adds what needs the robot: known joints, mimic joints, position limits, named states.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from description import Description
from planner.errors import InvalidRequest, JointLimitViolation
from planner.scene import Obstacle, validate_obstacles

# Slack on position limits for values that went through a float round trip [rad].
_LIMIT_EPS = 1e-9


def joint_values(description: Description, values: Mapping[str, float] | None, *,
                 field: str, fill: bool = True) -> dict[str, float]:
    """Check a ``{joint: value}`` map: actuated joints only, within position limits.

    Args:
        values: joint values [rad]; ``None`` is an empty map.
        field: the request field named in errors (``start``, ``goal.joints``).
        fill: give every actuated joint missing from ``values`` the value 0.

    Returns:
        The values in actuated-joint order (all of them if ``fill``).

    Raises:
        InvalidRequest: an unknown joint, a fixed joint, or a mimic joint (naming its leader).
        JointLimitViolation: a value outside the joint's position limits.
    """
    robot = description.robot
    actuated = robot.actuated_joints
    values = dict(values or {})
    for name in values:
        if name in actuated:
            continue
        j = robot.joints.get(name)
        if j is not None and j.mimic is not None:
            raise InvalidRequest(
                f"{name} is a mimic joint ({j.mimic.multiplier:g} * {j.mimic.joint} "
                f"+ {j.mimic.offset:g}): command its leader {j.mimic.joint} instead",
                field=f"{field}.{name}", details={"joint": name, "leader": j.mimic.joint})
        what = f"a {j.type} joint" if j is not None else "not a joint of this robot"
        raise InvalidRequest(f"{name} is {what}; actuated joints: {', '.join(actuated)}",
                             field=f"{field}.{name}",
                             details={"joint": name, "actuated": list(actuated)})
    out: dict[str, float] = {}
    for name, (lo, hi) in zip(actuated, robot.position_limits(actuated)):
        if name not in values:
            if fill:
                out[name] = 0.0
            continue
        v = float(values[name])
        if not lo - _LIMIT_EPS <= v <= hi + _LIMIT_EPS:
            raise JointLimitViolation(name, v, float(lo), float(hi), field=f"{field}.{name}")
        out[name] = v
    return out


def obstacles(description: Description, items: Sequence[Mapping[str, Any]] | None
              ) -> tuple[Obstacle, ...]:
    """Build and cross-check obstacles (unique ids, no link names). Mesh obstacles are
    not accepted over the wire: the schema allows box, sphere and cylinder only."""
    obs = [Obstacle.from_mapping(o, where=f"obstacles[{i}]") for i, o in enumerate(items or ())]
    return validate_obstacles(obs, link_names=tuple(description.robot.links))
