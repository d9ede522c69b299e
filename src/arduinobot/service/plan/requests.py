"""Check the robot-dependent parts of validated wire requests: joint states, obstacles.

Shared by the service's workers and the ``--local`` commands, so both refuse alike.
Input has passed :func:`arduinobot.contract.wire.decode` (types, ranges, finiteness);
this adds what needs the robot: known joints, mimic joints, position limits, named states.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from arduinobot.description import Description
from arduinobot.planner.checks import check_joint_names, check_positions
from arduinobot.scene.obstacles import Obstacle, validate_obstacles


def joint_values(description: Description, values: Mapping[str, float] | None, *,
                 field: str) -> dict[str, float]:
    """Check a ``{joint: value}`` map: actuated joints only, within position limits.

    Args:
        values: joint values [rad]; ``None`` is an empty map.
        field: the request field named in errors (``start``, ``goal.joints``).

    Returns:
        Every actuated joint's value in actuated-joint order, 0 for a joint missing from
        ``values``.

    Raises:
        InvalidRequest: an unknown joint, a fixed joint, or a mimic joint (naming its leader).
        JointLimitViolation: a value outside the joint's position limits.
    """
    actuated = description.robot.actuated_joints
    values = dict(values or {})
    check_joint_names(description, values, field=field)
    names = [n for n in actuated if n in values]
    check_positions(names, [float(values[n]) for n in names],
                    description.robot.position_limits(tuple(names)), field=field)
    return {n: float(values.get(n, 0.0)) for n in actuated}


def obstacles(description: Description, items: Sequence[Mapping[str, Any]] | None
              ) -> tuple[Obstacle, ...]:
    """Build and cross-check obstacles (unique ids, no link names). Mesh obstacles are
    not accepted over the wire: the schema allows box, sphere and cylinder only."""
    obs = [Obstacle.from_mapping(o, where=f"obstacles[{i}]") for i, o in enumerate(items or ())]
    return validate_obstacles(obs, link_names=tuple(description.robot.links))
