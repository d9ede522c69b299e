"""Executing trajectories on a robot: the executor, its segments and stops, the report,
the robots (the real arm's serial driver, the MuJoCo twin) and :func:`simulate`.

Between the planner and its users: this package imports :mod:`planner` and
:mod:`description` only. The service's execute queryable (:mod:`service.execution`)
and the command line (``arduinobot execute``, ``plan --simulate``) both use it directly.
Nothing here is imported at package import (the command line loads it with the command
that needs it: numba and ruckig are not for a plain ``plan``), nor imports mujoco or
serial before a driver needs them. Where things are:

- :mod:`execution.executor`: :class:`~execution.executor.Executor`, its options and errors;
- :mod:`execution.segments`: :class:`~execution.segments.SampledTrajectory`,
  :func:`~execution.segments.check_fits`; :mod:`execution.stops`: smooth stops;
- :mod:`execution.report`: the execution report; :mod:`execution.joint_states`;
- :mod:`execution.robots`: the :class:`~execution.robots.base.Robot` interface, the
  drivers and :class:`~execution.robots.spec.RobotSpec`;
- :mod:`execution.simulate`: :func:`~execution.simulate.simulate` on the twin.
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
