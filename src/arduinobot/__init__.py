"""arduinobot: certified, time-parameterised motions for small arms, as a library and a
Zenoh service.

The public faces, re-exported here (each imported on first use, so ``import
arduinobot`` loads none of Zenoh, OMPL or FCL)::

    from arduinobot import PlannerClient          # talk to `arduinobot serve`
    from arduinobot import MotionPlanner, MotionRequest, JointGoal, load_description
    from arduinobot import PlanningError, ServiceError

The packages, floor by floor (each imports only those below it; tests/test_layers.py):

- ``contract``: codes, errors, ranges, caps, wire, schemas, the Zenoh config.
- ``scene``: shapes, poses, obstacles, attached objects, meshes sent inline.
- ``description``: URDF/xacro loading and checks (a link's geometry: a scene shape),
  the shipped arduinobot package.
- ``planner``: kinematics, collision and its proof, OMPL search, timing, tasks.
- ``execution``: the executor, the drivers, the MuJoCo twin.
- ``perception``: camera images to scene objects through markers (the ``see`` extra).
- ``ros2``: the rmw_zenoh wire.
- ``service``: the Zenoh queryables, the worker pool, the kept scene, execute, tasks.
- ``client``: the Python client library.
- ``viewer``: ``arduinobot view`` (optional: the ``view`` extra).
- ``cli``: the ``arduinobot`` command.
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from arduinobot.client.client import PlannerClient
    from arduinobot.client.errors import ServiceError
    from arduinobot.contract.codes import Code
    from arduinobot.contract.errors import PlanningError
    from arduinobot.description import Description, DescriptionError, load_description
    from arduinobot.planner.planning.goals import JointGoal, NamedGoal, PositionGoal
    from arduinobot.planner.planning.motion import MotionRequest, MotionResult
    from arduinobot.planner.planning.pipeline import MotionPlanner
    from arduinobot.scene.obstacles import Obstacle

logging.getLogger(__name__).addHandler(logging.NullHandler())

__version__ = "0.1.0"

# each public name -> the module that defines it
_PUBLIC: dict[str, str] = {
    "PlannerClient": "arduinobot.client.client",
    "ServiceError": "arduinobot.client.errors",
    "Code": "arduinobot.contract.codes",
    "PlanningError": "arduinobot.contract.errors",
    "Description": "arduinobot.description",
    "DescriptionError": "arduinobot.description",
    "load_description": "arduinobot.description",
    "MotionPlanner": "arduinobot.planner.planning.pipeline",
    "MotionRequest": "arduinobot.planner.planning.motion",
    "MotionResult": "arduinobot.planner.planning.motion",
    "JointGoal": "arduinobot.planner.planning.goals",
    "NamedGoal": "arduinobot.planner.planning.goals",
    "PositionGoal": "arduinobot.planner.planning.goals",
    "Obstacle": "arduinobot.scene.obstacles",
}

__all__ = [
    "Code",
    "Description",
    "DescriptionError",
    "JointGoal",
    "MotionPlanner",
    "MotionRequest",
    "MotionResult",
    "NamedGoal",
    "Obstacle",
    "PlannerClient",
    "PlanningError",
    "PositionGoal",
    "ServiceError",
    "load_description",
]


def __getattr__(name: str) -> Any:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'arduinobot' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # once: later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_PUBLIC})
