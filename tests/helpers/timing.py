"""Shared parts of the timing tests: the real robot, world, dynamics and limits.

Built on first use, not at import: ``from tests.helpers.timing import DYN`` builds the
description and its dynamics only, and the collision world (the costly one) only for the
modules that take ``WORLD``. Each is built once per process.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np

# a collision-free path with two corners (checked in test_blends_are_checked...)
WP = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0], [1.0, 1.0, -0.5, 0.0],
               [0.2, 1.0, -0.5, -0.3]])


@cache
def _desc():
    from arduinobot.description import load_description
    return load_description()


@cache
def _world():
    from arduinobot.planner.collision.world import CollisionWorld
    return CollisionWorld(_desc())


@cache
def _dyn():
    from arduinobot.planner.kinematics.dynamics import InverseDynamics
    return InverseDynamics(_desc().robot)


_LAZY = {
    "DESC": _desc,
    "WORLD": _world,
    "DYN": _dyn,
    "NAMES": lambda: tuple(_desc().robot.actuated_joints),
}


def __getattr__(name: str) -> Any:
    make = _LAZY.get(name)
    if make is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return make()


def active_limits(velocity_scaling: float = 1.0, acceleration_scaling: float = 1.0):
    """The robot's limits through the limits module."""
    from arduinobot.planner.kinematics.limits import JointLimits
    return JointLimits.from_description(_desc(), velocity_scaling=velocity_scaling,
                                        acceleration_scaling=acceleration_scaling)
