"""Shared fixtures of the timing tests: the real robot, world, dynamics and limits."""

from types import SimpleNamespace

import numpy as np

from description import load_description
from planner.collision.world import CollisionWorld
from planner.kinematics.dynamics import InverseDynamics

DESC = load_description()
WORLD = CollisionWorld(DESC)
DYN = InverseDynamics(DESC.robot)
NAMES = tuple(DESC.robot.actuated_joints)
# a collision-free path with two corners (checked in test_blends_are_checked...)
WP = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0], [1.0, 1.0, -0.5, 0.0],
               [0.2, 1.0, -0.5, -0.3]])


def active_limits(velocity_scaling: float = 1.0, acceleration_scaling: float = 1.0):
    """The robot's limits through the limits module (a numeric stand-in until it lands)."""
    try:
        from planner.kinematics.limits import JointLimits
    except ImportError:
        lo, hi = np.array(DESC.robot.position_limits(NAMES)).T
        return SimpleNamespace(lower=lo, upper=hi,
                               velocity=np.full(4, 10.0) * velocity_scaling,
                               acceleration=np.full(4, 20.0) * acceleration_scaling,
                               jerk=np.full(4, 200.0), effort=np.full(4, 30.0))
    return JointLimits.from_description(DESC, velocity_scaling=velocity_scaling,
                                        acceleration_scaling=acceleration_scaling)
