"""Shared fixtures of the timing tests: the real robot, world, dynamics and limits."""


import numpy as np

from arduinobot.description import load_description
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.dynamics import InverseDynamics

DESC = load_description()
WORLD = CollisionWorld(DESC)
DYN = InverseDynamics(DESC.robot)
NAMES = tuple(DESC.robot.actuated_joints)
# a collision-free path with two corners (checked in test_blends_are_checked...)
WP = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0], [1.0, 1.0, -0.5, 0.0],
               [0.2, 1.0, -0.5, -0.3]])


def active_limits(velocity_scaling: float = 1.0, acceleration_scaling: float = 1.0):
    """The robot's limits through the limits module."""
    from arduinobot.planner.kinematics.limits import JointLimits
    return JointLimits.from_description(DESC, velocity_scaling=velocity_scaling,
                                        acceleration_scaling=acceleration_scaling)
