"""Braking a moving arm to rest with ruckig, within the effort limits.

One mechanism for the planner's moving start (:mod:`arduinobot.planner.planning.moving_start`) and the
clients' stops of a running execution (:mod:`arduinobot.execution.stops`): ruckig's time-optimal,
jerk-limited brake, every joint on its own (the velocity interface), all reaching rest
together; and the search for the largest acceleration and jerk scale whose torques fit
the effort limits, because a heavy arm brakes by its motors' strength, not by its
acceleration limit.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Trajectory

from arduinobot.contract.errors import TrajectoryError
from arduinobot.planner.timing.trajectory import TorqueFn

#: [s] torques are checked this often along a ruckig motion ...
EFFORT_STEP = 1e-3
#: ... within this fraction of the effort limits: a margin for the peaks between the
#: samples, which a verifier's finer grid finds (measured: 1.9% over between 2 ms
#: samples, braking the shipped arm's base joint from 0.2 rad/s)
EFFORT_MARGIN = 0.95


def brake_to_rest(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, *, velocity: np.ndarray,
                  acceleration: np.ndarray, jerk: np.ndarray) -> Trajectory:
    """The time-optimal jerk-limited stop from (q, qd, qdd) to rest (zero velocity and
    acceleration), every joint within ``velocity`` [rad/s], ``acceleration`` [rad/s^2]
    and ``jerk`` [rad/s^3], all joints reaching rest together.

    Raises:
        TrajectoryError: ruckig found no stop or refused the inputs (``details.result``).
    """
    dof = len(q)
    inp = InputParameter(dof)
    inp.control_interface = ControlInterface.Velocity
    inp.current_position = [float(x) for x in q]
    inp.current_velocity = [float(x) for x in qd]
    inp.current_acceleration = [float(x) for x in qdd]
    inp.target_velocity = [0.0] * dof
    inp.target_acceleration = [0.0] * dof
    inp.max_velocity = [float(x) for x in velocity]
    inp.max_acceleration = [float(x) for x in acceleration]
    inp.max_jerk = [float(x) for x in jerk]
    tr = Trajectory(dof)
    try:
        res = Ruckig(dof).calculate(inp, tr)
    except RuckigError as e:  # inputs ruckig refuses (e.g. a zero limit)
        raise TrajectoryError(f"ruckig could not compute the stop: {e}".splitlines()[0],
                              details={"stage": "brake", "result": "invalid input"}) from e
    if res not in (Result.Working, Result.Finished):
        raise TrajectoryError(f"ruckig could not compute the stop: {res}",
                              details={"stage": "brake", "result": str(res)})
    return tr


def effort_ratio(trajectory: Trajectory, torques: TorqueFn, effort: np.ndarray, *,
                 step: float = EFFORT_STEP) -> float:
    """The largest |torque| / effort limit along ``trajectory`` on ``step`` [s] samples."""
    ts = np.linspace(0.0, trajectory.duration,
                     max(3, int(trajectory.duration / step) + 1))
    q, qd, qdd = (np.array(x, float) for x in zip(*(trajectory.at_time(float(t))
                                                   for t in ts)))
    tau = np.abs(np.asarray(torques(q, qd, qdd), float))
    return float(np.max(tau / np.asarray(effort, float)))


def effort_safe(make: Callable[[float], Trajectory], torques: TorqueFn, effort: np.ndarray,
                *, margin: float = EFFORT_MARGIN, tries: int = 25
                ) -> tuple[Trajectory, float]:
    """``make(scale)`` with the largest scale tried (1, 0.8, 0.64, ...) whose torques stay
    within ``margin`` of ``effort`` [N m] (see :func:`effort_ratio`); ``scale`` is for the
    caller to apply to acceleration and jerk.

    Returns the trajectory and its effort ratio: the last one tried, with a ratio above
    ``margin``, when none fits (the caller decides whether that is an error).
    """
    scale = 1.0
    for _ in range(max(tries, 1)):
        tr = make(scale)
        ratio = effort_ratio(tr, torques, effort)
        if ratio <= margin:
            break
        scale *= 0.8
    return tr, ratio
