"""What the executor plays: a planned trajectory read back from JSON, and ruckig motions.

A segment has ``joint_names``, ``duration`` [s] and ``evaluate(t) -> (q, qd, qdd)``
[rad, rad/s, rad/s^2], each shape (dof,), with ``t`` clamped to [0, duration].

- :class:`SampledTrajectory`: what ``arduinobot plan --json`` writes (the plan reply, or a
  bare ``JointTrajectory`` dict), read by :func:`parse_trajectory` (the viewer's reader
  too). Between samples it is the quintic that matches position,
  velocity and acceleration at both ends, so replaying at any rate follows the plan.
- ruckig's moves and stops: :mod:`arduinobot.execution.ruckig_segments`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from arduinobot.contract.codes import Code
from arduinobot.contract.packed import OPTIONAL, PackedError, unpack
from arduinobot.description import Description
from arduinobot.execution.robots.base import RobotError


class InvalidTrajectory(RobotError):
    """A trajectory file or body that cannot be played (shape, order, non-finite); the
    message names the field (also ``details.field``)."""

    code: str = Code.INVALID_TRAJECTORY


class MotionError(RobotError):
    """ruckig could not compute a stop or a move."""

    code: str = Code.MOTION_ERROR


class TrajectoryMismatch(InvalidTrajectory):
    """A trajectory that does not fit the robot it would be played on: a joint the robot
    lacks, or a position or velocity beyond the robot's limits (a plan for another
    robot). ``details`` name the joint and the limit."""


COLUMNS = ("positions", "velocities", "accelerations", "effort")
#: how far past a limit a sample may lie and still fit: sampling and JSON round-off
POSITION_SLACK = 1e-4  # [rad or m]
VELOCITY_SLACK = 1e-3  # relative


def check_fits(trajectory: SampledTrajectory, description: Description) -> None:
    """Refuse a trajectory that is not for ``description``'s robot.

    Raises:
        TrajectoryMismatch: naming the joint and the limit (or the joints it lacks).
    """
    from arduinobot.planner.kinematics.limits import JointLimits
    robot = description.robot
    actuated = robot.actuated_joints
    extra = [n for n in trajectory.joint_names if n not in actuated]
    if extra:
        raise TrajectoryMismatch(
            f"the trajectory moves {', '.join(extra)}, which robot '{robot.name}' does not "
            f"have (its joints: {', '.join(actuated)}): it was planned for another robot",
            details={"joints": extra, "robot": robot.name, "robot_joints": list(actuated)})
    lim = JointLimits.from_description(description, joint_names=trajectory.joint_names)
    lo, hi = trajectory.positions.min(axis=0), trajectory.positions.max(axis=0)
    vmax = np.abs(trajectory.velocities).max(axis=0)
    for j, name in enumerate(trajectory.joint_names):
        for limit, value, bound, over in (
                ("lower", lo[j], lim.lower[j], lo[j] < lim.lower[j] - POSITION_SLACK),
                ("upper", hi[j], lim.upper[j], hi[j] > lim.upper[j] + POSITION_SLACK),
                ("velocity", vmax[j], lim.velocity[j],
                 vmax[j] > lim.velocity[j] * (1 + VELOCITY_SLACK))):
            if over:
                value, bound = float(value), float(bound)
                raise TrajectoryMismatch(
                    f"the trajectory does not fit robot '{robot.name}': {name} reaches "
                    f"{value:.4f} against its {limit} limit {bound:.4f} (planned for "
                    "another robot, or with other limits)",
                    details={"joint": name, "limit": limit, "value": value, "bound": bound,
                             "robot": robot.name})


def _bad(field: str, problem: str) -> InvalidTrajectory:
    return InvalidTrajectory(f"{field} {problem}", details={"field": field})


def parse_trajectory(body: object) -> tuple[tuple[str, ...], np.ndarray, dict[str, np.ndarray]]:
    """The joint names, the points' ``time_from_start`` (m,) [s] (seconds, or ROS's
    ``{"sec", "nanosec"}``) and their :data:`COLUMNS`, each (m, dof): positions [rad],
    velocities [rad/s], accelerations [rad/s^2], effort [N m]; NaN in the rows of the
    points that lack an optional column.

    Raises:
        InvalidTrajectory: naming the field that is wrong.
    """
    if isinstance(body, Mapping) and "trajectory" in body:
        body = body["trajectory"]
    if not isinstance(body, Mapping):
        raise InvalidTrajectory("not a trajectory: expected a plan reply (plan --json) or "
                                "{joint_names, points}")
    names, points = body.get("joint_names"), body.get("points")
    if not (isinstance(names, list | tuple) and names
            and all(isinstance(n, str) for n in names)):
        raise _bad("trajectory.joint_names", "must be a non-empty list of names")
    if "packed" in body:
        if points is not None:
            raise _bad("trajectory", "holds both points and packed: send one")
        return _parse_packed(tuple(names), body["packed"])
    if not (isinstance(points, list | tuple) and points):
        raise _bad("trajectory.points", "must be a non-empty list")
    dof = len(names)
    cols = {k: np.full((len(points), dof), np.nan) for k in COLUMNS}
    times = np.empty(len(points))
    for k, pt in enumerate(points):
        where = f"trajectory.points[{k}]"
        if not isinstance(pt, Mapping):
            raise _bad(where, "must be an object")
        times[k] = _seconds(pt.get("time_from_start"), f"{where}.time_from_start")
        for key, col in cols.items():
            val = pt.get(key)
            if val is None or (key != "positions" and val == []):
                if key == "positions":
                    raise _bad(f"{where}.positions", "is required")
                continue
            try:
                row = np.array(val, float)
            except (TypeError, ValueError):
                raise _bad(f"{where}.{key}", "must be numbers") from None
            if row.shape != (dof,) or not np.all(np.isfinite(row)):
                raise _bad(f"{where}.{key}", f"must be {dof} finite numbers")
            col[k] = row
    if np.any(np.diff(times) < 0):
        raise _bad("trajectory.points", "time_from_start must not decrease")
    return tuple(names), times, cols


def _parse_packed(names: tuple[str, ...], packed: object
                  ) -> tuple[tuple[str, ...], np.ndarray, dict[str, np.ndarray]]:
    """:func:`parse_trajectory` of ``trajectory.packed`` (:mod:`arduinobot.contract.packed`)."""
    if not isinstance(packed, Mapping):
        raise _bad("trajectory.packed", "must be an object")
    try:
        times, *arrays = unpack(packed, len(names), optional=OPTIONAL)
    except PackedError as e:
        raise _bad(e.field, e.problem) from None
    if len(times) == 0:
        raise _bad("trajectory.packed.samples", "must be at least 1")
    m, dof = len(times), len(names)
    cols = {k: (a if a is not None else np.full((m, dof), np.nan))
            for k, a in zip(COLUMNS, arrays)}
    if np.any(np.diff(times) < 0):
        raise _bad("trajectory.packed.time_from_start", "must not decrease")
    return names, times, cols


def read_json(path: str | Path) -> Any:
    """The JSON in the file ``path`` (InvalidTrajectory if it cannot be read or parsed)."""
    try:
        return json.loads(Path(path).read_text("utf-8"))
    except OSError as e:
        raise InvalidTrajectory(f"cannot read {path}: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise InvalidTrajectory(f"{path} is not JSON: {e}") from None


def _seconds(value: object, field: str) -> float:
    if isinstance(value, Mapping):
        try:
            return float(value.get("sec", 0)) + float(value.get("nanosec", 0)) * 1e-9
        except (TypeError, ValueError):
            raise _bad(field, "must be seconds") from None
    try:
        t = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise _bad(field, "must be a number of seconds") from None
    if not np.isfinite(t) or t < 0:
        raise _bad(field, "must be a finite number >= 0")
    return t


class Segment(Protocol):
    """A timed motion the executor samples: positions [rad], velocities, accelerations."""

    @property
    def joint_names(self) -> tuple[str, ...]: ...

    @property
    def duration(self) -> float: ...

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


class TimedSamples(Protocol):
    """Samples of a timed trajectory, whatever holds them (a client's ``PlanReply``):
    ``times`` (m,) [s]; ``positions`` [rad], ``velocities`` [rad/s], ``accelerations``
    [rad/s²], (m, dof) each, columns in ``joint_names`` order."""

    @property
    def joint_names(self) -> Sequence[str]: ...
    @property
    def times(self) -> np.ndarray: ...
    @property
    def positions(self) -> np.ndarray: ...
    @property
    def velocities(self) -> np.ndarray: ...
    @property
    def accelerations(self) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class SampledTrajectory:
    """A timed trajectory given by samples: ``times`` (m,) [s] from 0, increasing;
    ``positions``, ``velocities``, ``accelerations`` (m, dof)."""

    joint_names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    def __post_init__(self) -> None:
        m, dof = len(self.times), len(self.joint_names)
        if m < 1 or dof < 1:
            raise InvalidTrajectory("a trajectory needs joint names and at least one point")
        for name in ("positions", "velocities", "accelerations"):
            a = np.asarray(getattr(self, name), float)
            if a.shape != (m, dof):
                raise InvalidTrajectory(f"{name} has shape {a.shape}, expected ({m}, {dof})",
                                        details={"field": name})
            if not np.all(np.isfinite(a)):
                raise InvalidTrajectory(f"{name} holds a non-finite value",
                                        details={"field": name})
            object.__setattr__(self, name, a)
        t = np.asarray(self.times, float)
        if not np.all(np.isfinite(t)) or abs(t[0]) > 1e-9 or np.any(np.diff(t) <= 0):
            raise InvalidTrajectory("time_from_start must start at 0 and increase strictly",
                                    details={"field": "time_from_start"})
        object.__setattr__(self, "times", t)

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @classmethod
    def from_json(cls, body: object) -> SampledTrajectory:
        """From a plan reply or a JointTrajectory dict (:func:`parse_trajectory`); missing
        velocities or accelerations are 0."""
        names, times, cols = parse_trajectory(body)
        return cls(names, times, cols["positions"],
                   *(np.nan_to_num(cols[k], nan=0.0) for k in ("velocities", "accelerations")))

    @classmethod
    def of(cls, samples: TimedSamples) -> SampledTrajectory:
        """From arrays already parsed (a plan reply of the client, :class:`TimedSamples`):
        a reply is parsed once, and the client needs no executor (nor ruckig) to hold one."""
        return cls(tuple(samples.joint_names), samples.times, samples.positions,
                   samples.velocities, samples.accelerations)

    @classmethod
    def load(cls, path: str | Path) -> SampledTrajectory:
        return cls.from_json(read_json(path))

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ts = self.times
        if t <= 0.0 or t >= ts[-1] or len(ts) == 1:
            i = 0 if t <= 0.0 else -1
            return self.positions[i].copy(), self.velocities[i].copy(), \
                self.accelerations[i].copy()
        k = int(np.searchsorted(ts, t, side="right")) - 1
        h = ts[k + 1] - ts[k]
        p0, v0, a0 = self.positions[k], self.velocities[k], self.accelerations[k]
        p1, v1, a1 = self.positions[k + 1], self.velocities[k + 1], self.accelerations[k + 1]
        d = p1 - p0 - v0 * h - 0.5 * a0 * h * h
        dv = v1 - v0 - a0 * h
        da = a1 - a0
        c3 = (10 * d - 4 * dv * h + 0.5 * da * h * h) / h**3
        c4 = (-15 * d + 7 * dv * h - da * h * h) / h**4
        c5 = (6 * d - 3 * dv * h + 0.5 * da * h * h) / h**5
        s = t - ts[k]
        q = p0 + s * (v0 + s * (0.5 * a0 + s * (c3 + s * (c4 + s * c5))))
        qd = v0 + s * (a0 + s * (3 * c3 + s * (4 * c4 + s * 5 * c5)))
        qdd = a0 + s * (6 * c3 + s * (12 * c4 + s * 20 * c5))
        return q, qd, qdd

    def for_joints(self, names: Sequence[str], hold: np.ndarray) -> SampledTrajectory:
        """The trajectory over ``names`` (the robot's joints, in its order): columns
        reordered, joints the trajectory does not name held at ``hold`` [rad].

        Raises:
            InvalidTrajectory: the trajectory names a joint the robot does not have.
        """
        extra = [n for n in self.joint_names if n not in names]
        if extra:
            raise InvalidTrajectory(f"the trajectory moves {', '.join(extra)}, which this "
                                    f"robot does not command ({', '.join(names)})",
                                    details={"joints": extra})
        m = len(self.times)
        cols = {n: i for i, n in enumerate(self.joint_names)}

        def take(a: np.ndarray, fill: np.ndarray) -> np.ndarray:
            return np.stack([a[:, cols[n]] if n in cols else np.full(m, fill[j])
                             for j, n in enumerate(names)], axis=1)
        z = np.zeros(len(names))
        return SampledTrajectory(tuple(names), self.times, take(self.positions, hold),
                                 take(self.velocities, z), take(self.accelerations, z))
