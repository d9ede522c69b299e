"""Robots that follow trajectories: one :class:`~arduinobot.execution.robots.base.Robot` interface,
a serial driver for the real arduinobot and a MuJoCo twin.

- ``base``: the :class:`~arduinobot.execution.robots.base.Robot` interface.
- ``spec``: which robot to open (the real arm, the twin, none).
- ``serial_arduinobot``: the real arm over a serial port (the course's protocol).
- ``sim_arduinobot``: the MuJoCo twin; ``mjcf``: its model built from a description;
  ``controller_gains``: its servo gains from a ros2_control controllers yaml;
  ``twin_tasks``: a planned task run on it, the picked objects as loose bodies.

Nothing here is imported by the core; :mod:`serial` and :mod:`mujoco` are imported only
by the driver that needs them.
"""
