"""Executing trajectories on a robot: the executor, its segments and stops, the report,
the robots (the real arm's serial driver, the MuJoCo twin) and :func:`simulate`.

Between the planner and its users: this package imports :mod:`planner` and
:mod:`description` only. The service's execute queryable (:mod:`arduinobot.service.execute.execution`)
and the command line (``arduinobot execute``, ``plan --simulate``) both use it directly.
Nothing here is imported at package import (the command line loads it with the command
that needs it: numba and ruckig are not for a plain ``plan``), nor imports mujoco or
serial before a driver needs them. Where things are:

- :mod:`arduinobot.execution.executor`: :class:`~arduinobot.execution.executor.Executor`, its options and errors;
- :mod:`arduinobot.execution.segments`: :class:`~arduinobot.execution.segments.SampledTrajectory`,
  :func:`~arduinobot.execution.segments.check_fits`; :mod:`arduinobot.execution.ruckig_segments`: ruckig's
  moves and stops; :mod:`arduinobot.execution.stops`: smooth stops;
- :mod:`arduinobot.execution.report`: the execution report; :mod:`arduinobot.execution.joint_states`;
- :mod:`arduinobot.execution.robots`: the :class:`~arduinobot.execution.robots.base.Robot` interface, the
  drivers and :class:`~arduinobot.execution.robots.spec.RobotSpec`;
- :mod:`arduinobot.execution.simulate`: :func:`~arduinobot.execution.simulate.simulate` on the twin.
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
