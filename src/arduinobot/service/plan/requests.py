"""Check the robot-dependent parts of validated wire requests: obstacles (joint states:
:func:`arduinobot.planner.checks.joint_values`).

Shared by the service's workers and the ``--local`` commands, so both refuse alike.
Input has passed :func:`arduinobot.contract.wire.decode` (types, ranges, finiteness);
this adds what needs the robot: known joints, mimic joints, position limits, named states.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from arduinobot.description import Description
from arduinobot.scene.obstacles import Obstacle, validate_obstacles


def obstacles(description: Description, items: Sequence[Mapping[str, Any]] | None
              ) -> tuple[Obstacle, ...]:
    """Build and cross-check obstacles (unique ids, no link names). Mesh obstacles are
    not accepted over the wire: the schema allows box, sphere and cylinder only."""
    obs = [Obstacle.from_mapping(o, where=f"obstacles[{i}]") for i, o in enumerate(items or ())]
    return validate_obstacles(obs, link_names=tuple(description.robot.links))
