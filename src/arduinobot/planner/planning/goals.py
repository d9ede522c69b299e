"""Planning goals: joint values, named SRDF states, tcp positions and poses, lines.

A goal with a tolerance (a sphere around a position, a band around each joint value,
per-axis bounds on an orientation) is reached exactly where that is possible; only where
the exact goal is out of reach or collides does the planner take a state inside the
tolerance, and the reply says how far from the exact goal it ended
(:mod:`arduinobot.planner.planning.reached`).

The goals are plain values checked when built; :mod:`arduinobot.planner.planning.goal_states`
resolves them to joint states (:mod:`arduinobot.planner.planning.tcp_goals` for tcp positions and
poses). A :class:`LineGoal` (a straight tcp move, Pilz's LIN) is planned by
:mod:`arduinobot.planner.planning.lines.straight_line`, not resolved to goal states.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from arduinobot.contract.errors import InvalidRequest, unknown_fields, unknown_names
from arduinobot.planner.kinematics.rotations import quaternion_of_rpy, unit_quaternion

Axis = Literal["x", "y", "z"]
AXES: tuple[Axis, ...] = ("x", "y", "z")


def _tolerance(value: object, where: str) -> float:
    """A tolerance [m or rad]: a finite number >= 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or value < 0:
        raise InvalidRequest(f"{value!r} is not a finite number >= 0", field=where)
    return float(value)


def _point(value: object, where: str) -> tuple[float, float, float]:
    try:
        p = tuple(float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        p = ()
    if len(p) != 3 or not all(math.isfinite(v) for v in p):
        raise InvalidRequest(f"{value!r} must be 3 finite numbers [m]", field=where)
    return p


@dataclass(frozen=True)
class JointGoal:
    """Target values [rad] for some or all joints of the group; the rest keep their start.
    ``where`` names the values in errors (the service's requests: ``goal.joints``).

    ``tolerances``: per joint of ``values``, how far [rad] from its value the goal may
    end (MoveIt's JointConstraint tolerance, symmetric); used only where the exact
    values collide."""

    values: Mapping[str, float]
    where: str = field(default="goal.values", repr=False)
    tolerances: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.values, Mapping) or not self.values:
            raise InvalidRequest("needs at least one joint value", field=self.where)
        for k, v in self.values.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InvalidRequest(f"{v!r} is not a finite number [rad]",
                                     field=f"{self.where}.{k}")
        object.__setattr__(self, "values", dict(self.values))
        if not isinstance(self.tolerances, Mapping):
            raise InvalidRequest("must map joint names to tolerances [rad]",
                                 field="goal.tolerances")
        tol = {}
        for k, v in self.tolerances.items():
            if k not in self.values:
                raise InvalidRequest(f"'{k}' has no goal value to be tolerant about",
                                     field=f"goal.tolerances.{k}")
            tol[k] = _tolerance(v, f"goal.tolerances.{k}")
        object.__setattr__(self, "tolerances", tol)


@dataclass(frozen=True)
class NamedGoal:
    """A named state from the SRDF (``home``, ``reach_forward``, ...)."""

    name: str


@dataclass(frozen=True)
class PositionGoal:
    """A tcp position [m] in the world frame, shape (3,).

    ``tolerance`` [m]: the radius of a sphere around it the tcp may end in (MoveIt's
    PositionConstraint with a sphere); used only where the exact position is out of
    reach or every state reaching it collides."""

    position: tuple[float, float, float]
    where: str = field(default="goal.position", repr=False)
    tolerance: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _point(self.position, self.where))
        object.__setattr__(self, "tolerance", _tolerance(self.tolerance, "goal.tolerance"))


@dataclass(frozen=True)
class PoseGoal:
    """A tcp position [m] and orientation in the world frame.

    ``orientation``: a unit quaternion (x, y, z, w) (ROS order; any non-zero one is
    normalised), see :meth:`from_rpy` for roll, pitch, yaw. ``orientation_tolerances``
    [rad]: per axis x, y, z of the goal's frame, the largest component of the rotation
    vector from the goal orientation to the reached one (MoveIt's OrientationConstraint,
    rotation-vector parameterisation); ``free_axes``: axes whose rotation is left free
    (a tolerance of pi). ``tolerance`` [m]: as :class:`PositionGoal`'s.
    """

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    orientation_tolerances: tuple[float, float, float] = (1e-3, 1e-3, 1e-3)
    free_axes: tuple[Axis, ...] = ()
    tolerance: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _point(self.position, "goal.position"))
        object.__setattr__(self, "orientation", unit_quaternion(self.orientation))
        tol = tuple(self.orientation_tolerances)
        if len(tol) != 3:
            raise InvalidRequest(f"{tol!r} must be 3 tolerances [rad] (x, y, z)",
                                 field="goal.orientation_tolerances")
        object.__setattr__(self, "orientation_tolerances", tuple(
            _tolerance(v, f"goal.orientation_tolerances.{a}") for v, a in zip(tol, AXES)))
        free = tuple(self.free_axes)
        for a in free:
            if a not in AXES:
                raise InvalidRequest(f"{a!r} is not an axis (x, y, z)", field="goal.free_axes")
        object.__setattr__(self, "free_axes", tuple(a for a in AXES if a in free))
        object.__setattr__(self, "tolerance", _tolerance(self.tolerance, "goal.tolerance"))

    @classmethod
    def from_rpy(cls, position: Sequence[float], rpy: Sequence[float], **options: object
                 ) -> PoseGoal:
        """A pose goal from roll, pitch, yaw [rad] (URDF's fixed-axis x-y-z order)."""
        return cls(position=tuple(position), orientation=quaternion_of_rpy(rpy),  # type: ignore[arg-type]
                   **options)  # type: ignore[arg-type]

    @property
    def limits(self) -> np.ndarray:
        """Per axis x, y, z the bound [rad] on the rotation vector's component: its
        tolerance, pi for a free axis (any rotation), shape (3,)."""
        return np.array([math.pi if a in self.free_axes else t
                         for a, t in zip(AXES, self.orientation_tolerances)])

    @property
    def constrained(self) -> tuple[Axis, ...]:
        """The axes whose rotation the goal bounds."""
        return tuple(a for a in AXES if a not in self.free_axes)


@dataclass(frozen=True)
class LineGoal:
    """A straight-line move of the tcp (Pilz's LIN) to ``position`` [m] (world frame),
    or by ``offset`` [m] in ``frame``: ``world``, or ``tcp`` (the tool frame at the start:
    the tcp's parent link's axes). Exactly one of the two."""

    position: tuple[float, float, float] | None = None
    offset: tuple[float, float, float] | None = None
    frame: Literal["world", "tcp"] = "world"

    def __post_init__(self) -> None:
        if (self.position is None) == (self.offset is None):
            raise InvalidRequest("give exactly one of position and offset", field="goal.line")
        if self.position is not None:
            object.__setattr__(self, "position", _point(self.position, "goal.line.position"))
        else:
            object.__setattr__(self, "offset", _point(self.offset, "goal.line.offset"))
        if self.frame not in ("world", "tcp"):
            raise InvalidRequest(f"{self.frame!r} is not a frame (world, tcp)",
                                 field="goal.line.frame")
        if self.frame == "tcp" and self.offset is None:
            raise InvalidRequest("frame tcp applies to an offset; a position is in the "
                                 "world frame", field="goal.line.frame")


Goal = JointGoal | NamedGoal | PositionGoal | PoseGoal | LineGoal


def check_goal(goal: object) -> None:
    """The one goal-type check, run when a request is built (:class:`MotionRequest`,
    :class:`PathRequest`); every layer below trusts it.

    Raises:
        InvalidRequest: ``goal`` is none of :data:`Goal`'s types.
    """
    if not isinstance(goal, (JointGoal, NamedGoal, PositionGoal, PoseGoal, LineGoal)):
        raise InvalidRequest(f"unknown goal type {type(goal).__name__}", field="goal")


_FORMS = ("joints", "named", "position", "line")
#: every key of a goal object (plan_request.json's goal), for a typo's "did you mean"
_GOAL_KEYS = (*_FORMS, "tolerances", "tolerance", "orientation", "free_axes",
              "orientation_tolerances")


def goal_from_mapping(data: object, where: str = "goal") -> Goal:
    """A goal's JSON form (``src/arduinobot/contract/schema/plan_request.json``'s ``goal``, a
    task's move step): exactly one of ``joints``, ``named``, ``position`` (a pose with
    ``orientation``), ``line``; the one parser of it. Errors name ``where...``."""
    if not isinstance(data, Mapping):
        raise InvalidRequest("must be a goal object (joints, named, position or line)",
                             field=where)
    forms = [k for k in _FORMS if k in data]
    if len(forms) != 1:
        guess = [k for k in data if isinstance(k, str) and k not in _GOAL_KEYS]
        raise InvalidRequest("give exactly one of joints, named, position, line" + (
            f"; unknown {unknown_names(guess, _GOAL_KEYS)}" if guess else ""), field=where)
    if "joints" in data:
        if not isinstance(data["joints"], Mapping):
            raise InvalidRequest("must map joint names to values [rad]", field=f"{where}.joints")
        return JointGoal(dict(data["joints"]), where=f"{where}.joints",
                         tolerances=dict(data.get("tolerances", {})))
    if "named" in data:
        if not isinstance(data["named"], str):
            raise InvalidRequest("must be a state name", field=f"{where}.named")
        return NamedGoal(data["named"])
    if "line" in data:
        return line_from_mapping(data["line"], f"{where}.line")
    tolerance = _tolerance(data.get("tolerance", 0.0), f"{where}.tolerance")
    position = data["position"]
    if "orientation" not in data:
        return PositionGoal(position, where=f"{where}.position", tolerance=tolerance)
    o = data["orientation"]
    if not isinstance(o, Mapping) or ("quaternion" in o) == ("rpy" in o):
        raise InvalidRequest("give exactly one of quaternion, rpy", field=f"{where}.orientation")
    quat = o["quaternion"] if "quaternion" in o else quaternion_of_rpy(o["rpy"])
    options: dict[str, Any] = {"tolerance": tolerance,
                               "free_axes": tuple(data.get("free_axes", ()))}
    if "orientation_tolerances" in data:
        options["orientation_tolerances"] = tuple(data["orientation_tolerances"])
    return PoseGoal(position=tuple(position), orientation=tuple(quat), **options)


def line_from_mapping(data: object, where: str) -> LineGoal:
    """A line goal's JSON form: ``{position}`` or ``{offset, frame}``."""
    if not isinstance(data, Mapping):
        raise InvalidRequest("must be {position} or {offset, frame}", field=where)
    extra = sorted(set(data) - {"position", "offset", "frame"})
    if extra:
        raise InvalidRequest(unknown_fields(extra, {"position", "offset", "frame"}),
                             field=where)
    return LineGoal(position=data.get("position"), offset=data.get("offset"),
                    frame=data.get("frame", "world"))
