"""The :class:`Robot` interface: joint setpoints in, joint state out.

A robot is driven tick by tick by :mod:`arduinobot.execution.executor`: each tick it gets one setpoint
(:meth:`Robot.command`), then the tick's time passes (:meth:`Robot.advance`: a simulator
steps its physics, hardware does nothing, the executor's clock paces the wall time), and
:meth:`Robot.state` reports where it is. Setpoints name the actuated joints of the
description in its order; states also carry the mimic joints (``multiplier * leader +
offset``), as ROS ``joint_states`` do.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.codes import Code
from arduinobot.description import Description


class RobotError(Exception):
    """Root of every robot driver and execution error. ``details`` is JSON-ready."""

    code: str = Code.ROBOT_ERROR

    def __init__(self, message: str, *, details: Mapping[str, object] | None = None) -> None:
        self.message = message
        self.details = dict(details or {})
        super().__init__(message)


class PortNotFound(RobotError):
    """The serial port does not exist."""

    code: str = Code.PORT_NOT_FOUND


class PortBusy(RobotError):
    """Another process holds the serial port."""

    code: str = Code.PORT_BUSY


class PortError(RobotError):
    """The serial port failed to open or to take a write."""

    code: str = Code.PORT_ERROR


class UnsupportedRobot(RobotError):
    """The description does not fit the driver (e.g. not four actuated joints)."""

    code: str = Code.UNSUPPORTED_ROBOT


class InvalidSetpoint(RobotError):
    """A setpoint of the wrong length or with a non-finite value."""

    code: str = Code.INVALID_SETPOINT


@dataclass(frozen=True)
class JointState:
    """sensor_msgs/JointState-shaped: per joint ``positions`` [rad], ``velocities``
    [rad/s] and ``efforts`` [N m] (None when the robot cannot tell), at ``stamp`` [s]
    (the robot's own clock: seconds since it was opened)."""

    names: tuple[str, ...]
    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    efforts: tuple[float, ...] | None
    stamp: float

    def to_dict(self) -> dict[str, object]:
        return {"stamp": self.stamp, "name": list(self.names), "position": list(self.positions),
                "velocity": list(self.velocities),
                "effort": None if self.efforts is None else list(self.efforts)}

    def actuated(self, names: Sequence[str]) -> np.ndarray:
        """The positions [rad] of ``names``, shape (len(names),)."""
        idx = {n: i for i, n in enumerate(self.names)}
        return np.array([self.positions[idx[n]] for n in names], float)


@dataclass(frozen=True)
class MimicMap:
    """How the mimic joints follow the actuated ones: ``names`` are actuated then mimic
    joints; ``leader``, ``multiplier``, ``offset`` per mimic joint."""

    actuated: tuple[str, ...]
    mimics: tuple[str, ...]
    leader: tuple[int, ...]
    multiplier: tuple[float, ...]
    offset: tuple[float, ...]

    @classmethod
    def from_description(cls, description: Description) -> MimicMap:
        robot = description.robot
        act, mims = tuple(robot.actuated_joints), tuple(robot.mimic_joints)
        ms = [robot.joints[n].mimic for n in mims]
        return cls(act, mims, tuple(act.index(m.joint) for m in ms),  # type: ignore[union-attr]
                   tuple(float(m.multiplier) for m in ms),  # type: ignore[union-attr]
                   tuple(float(m.offset) for m in ms))  # type: ignore[union-attr]

    @property
    def names(self) -> tuple[str, ...]:
        return self.actuated + self.mimics

    def expand(self, q: np.ndarray, *, rate: bool = False) -> np.ndarray:
        """Actuated values (dof,) -> every joint's (dof + mimics,); ``rate`` drops the
        offsets (for velocities and efforts)."""
        q = np.asarray(q, float)
        extra = [m * q[i] + (0.0 if rate else o)
                 for i, m, o in zip(self.leader, self.multiplier, self.offset)]
        return np.concatenate([q, np.array(extra, float)])


def initial_positions(description: Description, names: Sequence[str]) -> np.ndarray:
    """The positions [rad] ``names`` start at: ``initial_positions.yaml``'s, else 0."""
    init: Mapping[str, float] = description.initial_positions or {}
    return np.array([float(init.get(n, 0.0)) for n in names], float)


def check_setpoint(values: Sequence[float] | np.ndarray, names: Sequence[str],
                   what: str = "positions") -> np.ndarray:
    """``values`` as an array of shape (len(names),), all finite.

    Raises:
        InvalidSetpoint: wrong length or a non-finite value.
    """
    a = np.asarray(values, float).reshape(-1)
    if a.shape != (len(names),):
        raise InvalidSetpoint(f"{what}: {a.size} values for {len(names)} joints "
                              f"({', '.join(names)})", details={"joints": list(names)})
    bad = [n for n, v in zip(names, a) if not math.isfinite(float(v))]
    if bad:
        raise InvalidSetpoint(f"{what}: non-finite value for {', '.join(bad)}",
                              details={"joints": bad})
    return a


class Robot(abc.ABC):
    """A robot that follows joint setpoints.

    Attributes:
        joint_names: the commanded (actuated) joints, the description's order.
        state_names: ``joint_names`` then the mimic joints.
        realtime_only: True for hardware: it must be paced by the wall clock.
        feedback: True if :meth:`state` reads the positions back from the robot; False
            if it is the last command (open loop): a whole execution then reports
            ``written``, not ``completed``.
    """

    joint_names: tuple[str, ...]
    state_names: tuple[str, ...]
    realtime_only: bool = True
    feedback: bool = False

    @abc.abstractmethod
    def command(self, positions: Sequence[float] | np.ndarray,
                velocities: Sequence[float] | np.ndarray | None = None,
                accelerations: Sequence[float] | np.ndarray | None = None, *,
                jerks: Sequence[float] | np.ndarray | None = None) -> None:
        """The setpoint for the coming tick: ``positions`` [rad], optionally the
        ``velocities`` [rad/s], ``accelerations`` [rad/s^2] and the tick's mean ``jerks``
        [rad/s^3] along the trajectory (for a servo that interpolates within the tick
        and feeds forward; hardware may ignore them)."""

    @abc.abstractmethod
    def advance(self, dt: float) -> None:
        """Let ``dt`` [s] of the robot's time pass under the current setpoint."""

    @abc.abstractmethod
    def state(self) -> JointState:
        """Where the robot is now (hardware without feedback: where it was told to be)."""

    def close(self) -> None:  # noqa: B027 -- optional for drivers holding nothing
        """Release the hardware or the simulator."""

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
