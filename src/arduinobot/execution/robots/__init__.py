"""Robots that follow trajectories: one :class:`~arduinobot.execution.robots.base.Robot` interface,
a serial driver for the real arduinobot, a MuJoCo twin, plug-in drivers and the Feetech
bus driver.

- ``base``: :class:`Robot`, :class:`JointState`, the mimic map, the port errors;
- ``serial_arduinobot``: the course's Arduino over serial; ``serial_port``: opening a
  serial port, its failures coded (every serial driver's);
- ``sim_arduinobot``, ``mjcf``, ``controller_gains``, ``twin_tasks``, ``twin_clouds``,
  ``loose_state``: the MuJoCo twin;
- ``plugin``: ``--driver NAME|module:Class``, the :class:`Driver` protocol a plug-in
  meets, the ``arduinobot.drivers`` entry points (docs/drivers.md);
- ``feetech/``: Feetech STS/SCS bus servos (LeRobot's SO-100/SO-101);
- ``spec``: :class:`RobotSpec`, which of them the command line and the service open.

- ``base``: the :class:`~arduinobot.execution.robots.base.Robot` interface.
- ``spec``: which robot to open (the real arm, the twin, none).
- ``serial_arduinobot``: the real arm over a serial port (the course's protocol).
- ``sim_arduinobot``: the MuJoCo twin; ``mjcf``: its model built from a description;
  ``controller_gains``: its servo gains from a ros2_control controllers yaml;
  ``twin_tasks``: a planned task run on it, the picked objects as loose bodies;
  ``twin_clouds``: a kept point cloud's cells as its static boxes; ``loose_state``: a
  task's loose objects kept across a rebuild of the twin's model.

Nothing here is imported by the core; :mod:`serial` and :mod:`mujoco` are imported only
by the driver that needs them.
"""
