"""Ruckig's segments for the executor: jerk-limited moves and stops
(:func:`move_segment`, :func:`stop_segment`), a stop along a segment's own path
(:class:`PathStop`) and the rest of a segment from a point on it (:class:`RestOf`); each is a
:class:`~arduinobot.execution.segments.Segment`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from ruckig import ControlInterface, InputParameter, Result, Ruckig, Synchronization, Trajectory

from arduinobot.contract.errors import TrajectoryError
from arduinobot.execution.segments import MotionError, Segment
from arduinobot.planner.timing.braking import brake_to_rest


class RuckigSegment:
    """A ruckig trajectory as a segment (positions [rad])."""

    def __init__(self, joint_names: Sequence[str], trajectory: Trajectory) -> None:
        self.joint_names = tuple(joint_names)
        self.trajectory = trajectory

    @property
    def duration(self) -> float:
        return float(self.trajectory.duration)

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, v, a = self.trajectory.at_time(min(max(float(t), 0.0), self.duration))
        return np.array(p, float), np.array(v, float), np.array(a, float)

    def position_extrema(self) -> tuple[np.ndarray, np.ndarray]:
        ext = self.trajectory.position_extrema
        return np.array([e.min for e in ext]), np.array([e.max for e in ext])


def _calculate(inp: InputParameter, dof: int, what: str) -> Trajectory:
    tr = Trajectory(dof)
    res = Ruckig(dof).calculate(inp, tr)
    if res not in (Result.Working, Result.Finished):
        raise MotionError(f"ruckig could not compute the {what}: {res}",
                          details={"result": str(res)})
    return tr


def stop_segment(joint_names: Sequence[str], q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                 *, velocity: np.ndarray, acceleration: np.ndarray, jerk: np.ndarray
                 ) -> RuckigSegment:
    """The time-optimal jerk-limited stop from (q, qd, qdd) to rest (zero velocity and
    acceleration), every joint within ``velocity`` [rad/s], ``acceleration`` [rad/s^2]
    and ``jerk`` [rad/s^3], all joints reaching rest together."""
    try:
        tr = brake_to_rest(q, qd, qdd, velocity=velocity, acceleration=acceleration,
                           jerk=jerk)
    except TrajectoryError as e:
        raise MotionError(e.message, details=dict(e.details)) from e
    return RuckigSegment(joint_names, tr)


def move_segment(joint_names: Sequence[str], start: np.ndarray, goal: np.ndarray, *,
                 velocity: np.ndarray, acceleration: np.ndarray, jerk: np.ndarray
                 ) -> RuckigSegment:
    """A jerk-limited, time-synchronised move from rest at ``start`` to rest at ``goal``
    [rad] (a straight line in joint space: no collision check)."""
    dof = len(joint_names)
    inp = InputParameter(dof)  # velocities and accelerations 0: rest to rest
    inp.max_velocity = [float(v) for v in velocity]
    inp.max_acceleration = [float(v) for v in acceleration]
    inp.max_jerk = [float(v) for v in jerk]
    inp.current_position = [float(v) for v in start]
    inp.target_position = [float(v) for v in goal]
    inp.synchronization = Synchronization.Phase  # rest to rest: a straight line
    return RuckigSegment(joint_names, _calculate(inp, dof, "move"))


class PathStop:
    """Braking along a segment's own path: the segment's time ``s`` slows from speed 1 to
    0 with a jerk-limited ruckig profile, ``q(t) = Q(s(t))``. The positions stay on the
    planned (collision-checked, within-limits) path and never pass its end.

    Joint velocity ``Q' s'``, acceleration ``Q'' s'^2 + Q' s''``.
    """

    def __init__(self, segment: Segment, s0: float, deceleration: float, jerk: float
                 ) -> None:
        self.segment, self.s0 = segment, float(s0)
        self.joint_names = segment.joint_names
        inp = InputParameter(1)  # target velocity and acceleration 0: at rest
        inp.control_interface = ControlInterface.Velocity
        inp.current_position = [self.s0]
        inp.current_velocity = [1.0]
        inp.max_velocity = [1.0 + 1e-9]
        inp.max_acceleration = [float(deceleration)]
        inp.max_jerk = [float(jerk)]
        self.profile = _calculate(inp, 1, "stop along the path")
        self.s_end = float(self.profile.position_extrema[0].max)

    @property
    def duration(self) -> float:
        return float(self.profile.duration)

    @property
    def passes_end(self) -> bool:
        """True if braking would need more path than is left."""
        return self.s_end > self.segment.duration

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, v, a = self.profile.at_time(min(max(float(t), 0.0), self.duration))
        s, sd, sdd = float(p[0]), float(v[0]), float(a[0])
        if t >= self.duration:
            sd = sdd = 0.0
        q, q1, q2 = self.segment.evaluate(s)
        return q, q1 * sd, q2 * sd * sd + q1 * sdd


class RestOf:
    """``segment`` from its time ``s0`` on, re-timed from 0."""

    def __init__(self, segment: Segment, s0: float) -> None:
        self.segment, self.s0 = segment, float(s0)
        self.joint_names = segment.joint_names

    @property
    def duration(self) -> float:
        return max(0.0, self.segment.duration - self.s0)

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.segment.evaluate(self.s0 + min(max(float(t), 0.0), self.duration))
