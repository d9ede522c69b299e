"""`arduinobot view`: a web 3D viewer of a robot, its collisions and its trajectories.

A package of its own above ``clients`` (it plans and follows through
:class:`arduinobot.client.client.PlannerClient`): the core (``planner``, ``service``,
``execution``, ``description``, ``ros2``) never imports it, and ``clients`` only inside
the functions that need it (``arduinobot view``, ``plan --plot``). Its libraries, viser
and matplotlib, are optional dependencies (the ``view`` extra), imported only where it
draws, through :func:`require`.
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
