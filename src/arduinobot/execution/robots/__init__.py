"""Robots that follow trajectories: one :class:`~arduinobot.execution.robots.base.Robot` interface,
a serial driver for the real arduinobot and a MuJoCo twin.

Nothing here is imported by the core; :mod:`serial` and :mod:`mujoco` are imported only
by the driver that needs them.
"""
