"""`arduinobot view`: a web 3D viewer of a robot, its collisions and its trajectories.

A package of its own above ``client`` (it plans and follows through
:class:`arduinobot.client.client.PlannerClient`): nothing below it imports it, and
``cli`` only inside the commands that draw (``arduinobot view``, ``plan --plot``;
tests/test_layers.py). Its libraries, viser and matplotlib, are optional dependencies
(the ``view`` extra), imported only where it draws, through :func:`require`.

- ``app``: the viewer, a viser server (the robot, a slider per joint, collisions).
- ``geometry``: what it draws, without drawing (meshes, colours, obstacles, framing);
  ``still``: a still picture without a browser (``view --png``).
- ``plan_panel``: the planning panel; ``planning``: where its Plan button plans
  (in-process or a running service).
- ``playback``: the playback panel; ``trajectory``: a trajectory to play;
  ``task_view``: a task with each step marked; ``plots``: positions, velocities,
  accelerations and efforts with limits.
- ``follow``: following a running execution live; ``scene_follow``: following the kept
  scene; ``scene_view``: the kept scene as drawn.
"""

from __future__ import annotations

import importlib
from types import ModuleType

INSTALL_HINT = "pip install -e '.[view]'"


class ViewerUnavailable(ImportError):
    """An optional dependency of the viewer is not installed."""


def require(module: str) -> ModuleType:
    """Import an optional dependency, or raise :class:`ViewerUnavailable` saying how to
    install it."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ViewerUnavailable(
            f"the viewer needs '{module.split('.')[0]}', which is not installed "
            f"({e}); install the viewer's extras with: {INSTALL_HINT}") from e
