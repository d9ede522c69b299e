"""Planning goals: joint values, named SRDF states, tcp positions and poses, lines.

Each goal resolves to one or more full joint vectors; a tcp position resolves to every
collision-free IK solution, so the planner may reach whichever is easiest. A goal with a
tolerance (a sphere around a position, a band around each joint value, per-axis bounds on
an orientation) is reached exactly where that is possible; only where the exact goal
is out of reach or collides does the planner take a state inside the tolerance, and the
reply says how far from the exact goal it ended (:mod:`planner.planning.reached`).

A pose goal (a position and an orientation) is planned only for a group whose joints can
choose the tcp's orientation; for a position-only group (the arduinobot's three joints)
one whose orientation the position does not already give is refused with
:class:`~planner.errors.OrientationNotControllable`, naming the axes the group turns the
tool about, never answered with a different orientation.

A :class:`LineGoal` (a straight tcp move, Pilz's LIN) is planned by
:mod:`planner.planning.straight_line`, not resolved to goal states here.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, TypedDict

import numpy as np

from description import Description, Tcp
from description.errors import SrdfError

from ..checks import check_joint_names, check_positions
from ..collision.world import CollisionWorld
from ..errors import (
    GoalInCollision,
    GoalOutOfReach,
    InvalidRequest,
    OrientationNotControllable,
    PlanningError,
)
from ..kinematics.rotations import (
    matrix_of_quaternion,
    quaternion_of_matrix,
    quaternion_of_rpy,
    rotation_error,
    rpy_of_matrix,
    unit_quaternion,
)

if TYPE_CHECKING:
    from ..kinematics.ik import IkSolution
    from ..kinematics.ik_numeric import Chain

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


def resolve_group(description: Description, group: str | None, goal: Goal) -> str:
    """The planning group of a request: ``group`` if given (it must exist); for a named
    goal, the group that defines the state; else the description's default group.

    Raises:
        InvalidRequest: an unknown group (naming the known ones), or a named state that
            several groups define when no group was given (naming them).
    """
    srdf = description.srdf
    known = (*(srdf.groups if srdf is not None else ()), "all")  # the groups a request may name
    if group is not None:
        if not isinstance(group, str) or group not in known:
            raise InvalidRequest(f"{group!r} is not a group of this robot (groups: "
                                 f"{', '.join(known)})", field="group",
                                 details={"groups": list(known)})
        return group
    if isinstance(goal, NamedGoal) and srdf is not None:
        try:
            return srdf.named_state(goal.name).group
        except SrdfError as e:
            raise InvalidRequest(e.message, field="goal.named",
                                 details={"hint": e.hint} if e.hint else None) from None
    return description.default_group()


def check_goal(goal: object) -> None:
    """The one goal-type check, run when a request is built (:class:`MotionRequest`,
    :class:`PathRequest`); every layer below trusts it.

    Raises:
        InvalidRequest: ``goal`` is none of :data:`Goal`'s types.
    """
    if not isinstance(goal, (JointGoal, NamedGoal, PositionGoal, PoseGoal, LineGoal)):
        raise InvalidRequest(f"unknown goal type {type(goal).__name__}", field="goal")


def check_limits(world: CollisionWorld, q: np.ndarray, *, field: str) -> None:
    """Raise :class:`JointLimitViolation` naming the first joint outside its limits."""
    names = world.kin.joint_names
    check_positions(names, q, world.description.robot.position_limits(names), field=field)


def _tcp(description: Description) -> Tcp:
    if description.tcp is None:
        raise InvalidRequest("the model has no tcp", field="goal.position")
    return description.tcp


def tcp_joints(description: Description, group_joints: Sequence[str]) -> tuple[str, ...]:
    """The joints of ``group_joints`` that move the tool point (those IK solves for).

    Raises:
        InvalidRequest: the model has no tcp, or no joint of the group moves it.
    """
    tcp = _tcp(description)
    above = {j.name for j in description.robot.link_path(tcp.parent_link) if j.movable}
    joints = tuple(j for j in group_joints if j in above)
    if not joints:
        raise InvalidRequest(f"no joint of the group ({', '.join(group_joints)}) moves the "
                             f"tcp on {tcp.parent_link}", field="group")
    return joints


def named_values(description: Description, name: str, group: str,
                 actuated: Mapping[str, int]) -> dict[str, float]:
    """The actuated joint values [rad] of named state ``name``, looked up in ``group``
    (for ``all``: the one group that defines it).

    Raises:
        InvalidRequest: no SRDF, an unknown state, or an ambiguous name.
    """
    srdf = description.srdf
    if srdf is None:
        raise InvalidRequest("the model has no SRDF, so no named states (give "
                             "--moveit-config)", field="goal.named")
    try:
        state = srdf.named_state(name, None if group == "all" else group)
    except SrdfError as e:
        raise InvalidRequest(e.message + (f" ({e.hint})" if e.hint else ""),
                             field="goal.named",
                             details={"known": list(srdf.state_names())}) from None
    return {k: v for k, v in state.values.items() if k in actuated}


def resolve_goal(goal: Goal, *, world: CollisionWorld, description: Description,
                 start: np.ndarray, group_joints: Sequence[str],
                 group: str = "all") -> np.ndarray:
    """Every candidate goal state for ``goal``, shape (k, dof), k >= 1, collision-free.

    Joints outside ``group_joints`` keep their ``start`` value.

    Raises:
        InvalidRequest: a joint outside the group, an unknown named state.
        JointLimitViolation: a joint goal outside its limits.
        GoalOutOfReach: no IK solution within the limits.
        GoalInCollision: every candidate collides (the pairs of the first one).
    """
    names = world.kin.joint_names
    idx = {n: i for i, n in enumerate(names)}
    if isinstance(goal, NamedGoal):
        goal = JointGoal(named_values(description, goal.name, group, idx))
    if isinstance(goal, JointGoal):
        q = start.copy()
        check_joint_names(description, goal.values, field=goal.where)
        for k, v in goal.values.items():
            if k not in group_joints:
                raise InvalidRequest(f"'{k}' is not in the planning group "
                                     f"({', '.join(group_joints)})", field=f"{goal.where}.{k}")
            q[idx[k]] = v
        try:
            check_limits(world, q, field=goal.where)
            chk = world.check(q)
            if not chk.valid:
                raise GoalInCollision("the goal state collides", pairs=chk.pairs,
                                      q=dict(zip(names, map(float, q))))
        except PlanningError:
            if not goal.tolerances:
                raise
            return _within_joint_tolerances(goal, q, world=world, idx=idx)
        return q[None]
    if isinstance(goal, PoseGoal):
        return _pose_candidates(goal, world=world, description=description, start=start,
                                group_joints=group_joints)
    if isinstance(goal, LineGoal):
        raise InvalidRequest("a line is planned by the straight-line strategy, not "
                             "resolved to goal states", field="goal.line")
    # a PositionGoal: the request checked the goal's type when it was built (check_goal)
    return _position_candidates(goal, world=world, description=description, start=start,
                                group_joints=group_joints)


def _within_joint_tolerances(goal: JointGoal, q: np.ndarray, *, world: CollisionWorld,
                             idx: Mapping[str, int]) -> np.ndarray:
    """Collision-free states within the limits and the goal's tolerances, nearest the
    exact goal first (each tolerant joint at -tol, -tol/2, 0, tol/2, tol); raises the
    exact goal's error when there is none."""
    import itertools

    names = world.kin.joint_names
    lim = world.description.robot.position_limits(names)
    tolerant = [(idx[k], t) for k, t in goal.tolerances.items() if t > 0]
    steps = [(i, (-t, -t / 2, 0.0, t / 2, t)) for i, t in tolerant][:6]
    found = []
    for combo in itertools.product(*(d for _, d in steps)):
        c = q.copy()
        for (i, _), dv in zip(steps, combo):
            c[i] += dv
        if np.all(c >= lim[:, 0] - 1e-12) and np.all(c <= lim[:, 1] + 1e-12) \
                and world.check(c).valid:
            found.append(c)
    if not found:
        check_limits(world, q, field=goal.where)  # the exact goal's own error
        chk = world.check(q)
        raise GoalInCollision("every state within the goal's tolerances collides",
                              pairs=chk.pairs, q=dict(zip(names, map(float, q))))
    found.sort(key=lambda c: float(np.abs(c - q).max()))
    return np.array(found)


def _sphere_points(center: np.ndarray, radius: float) -> np.ndarray:
    # the 26 directions of a cube's faces, edges and corners, at the radius and half
    dirs = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], float) - 1.0
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    return np.concatenate([center + radius * dirs, center + 0.5 * radius * dirs])


def _position_candidates(goal: PositionGoal | PoseGoal, *, world: CollisionWorld,
                         description: Description, start: np.ndarray,
                         group_joints: Sequence[str]) -> np.ndarray:
    """Collision-free IK states for the exact position; where there is none and the
    goal has a tolerance, for points inside its sphere (nearest the goal first)."""
    try:
        return _exact_position(goal.position, world=world, description=description,
                               start=start, group_joints=group_joints)
    except (GoalOutOfReach, GoalInCollision):
        if goal.tolerance <= 0:
            raise
        first = sys.exc_info()[1]
    center = np.asarray(goal.position, float)
    found: list[np.ndarray] = []
    for p in _sphere_points(center, goal.tolerance):
        try:
            found += list(_exact_position(tuple(p), world=world, description=description,
                                          start=start, group_joints=group_joints))
        except (GoalOutOfReach, GoalInCollision):
            continue
    if not found:
        raise first  # type: ignore[misc]
    tcp = _tcp(description)
    dist = [float(np.linalg.norm(world.kin.point_position(q, tcp.parent_link, tcp.xyz)
                                 - center)) for q in found]
    return np.array([found[i] for i in np.argsort(dist, kind="stable")])


def _free_solutions(sols: Sequence[IkSolution], *, world: CollisionWorld,
                    what: str) -> np.ndarray:
    """The states of the IK solutions that are collision-free.

    Raises:
        GoalInCollision: every one collides; the pairs are those of the first.
    """
    free, first_pairs = [], None
    for s in sols:
        chk = world.check(s.q)
        if chk.valid:
            free.append(np.asarray(s.q, float))
        elif first_pairs is None:
            first_pairs = chk.pairs
    if not free:
        raise GoalInCollision(f"every IK solution ({len(sols)}) for {what} collides",
                              pairs=first_pairs or ())
    return np.array(free)


def _exact_position(position: tuple[float, float, float], *, world: CollisionWorld,
                    description: Description, start: np.ndarray,
                    group_joints: Sequence[str]) -> np.ndarray:
    from ..kinematics.ik import (
        position_ik,  # written alongside; imported late to keep startup light
    )

    ik_joints = tcp_joints(description, group_joints)
    sols = position_ik(world.kin, _tcp(description), position, joints=ik_joints,
                       q_fixed=start)
    if not sols:
        raise GoalOutOfReach(f"no joint state reaches {position}",
                             details={"position": list(position)})
    return _free_solutions(sols, world=world, what=str(position))


#: a chain with fewer joints moving the tcp has all of them placing its position
#: (position-only IK, like the course's ``position_only_ik: True``)
POSITION_JOINTS = 3


def _pose_candidates(goal: PoseGoal, *, world: CollisionWorld, description: Description,
                     start: np.ndarray, group_joints: Sequence[str]) -> np.ndarray:
    """Collision-free states reaching the pose within its tolerances.

    A position-only chain (at most three joints move the tcp) keeps the IK states of the
    position whose orientation is already within the goal's tolerances; when none is,
    :class:`OrientationNotControllable` names the axes the chain turns the tool about.
    """
    from ..kinematics.ik_numeric import build_chain
    from ..kinematics.ik_pose import pose_ik, tool_jacobian

    tcp = _tcp(description)
    ik_joints = tcp_joints(description, group_joints)
    chain = build_chain(world.kin, tcp, ik_joints)
    goal_r = matrix_of_quaternion(goal.orientation)
    limits = goal.limits
    if len(ik_joints) <= POSITION_JOINTS:
        cands = _position_candidates(goal, world=world, description=description,
                                     start=start, group_joints=group_joints)
        _, rots, _, jw = tool_jacobian(world.kin, tcp, chain, cands)
        err = rotation_error(goal_r, rots)
        ok = np.all(np.abs(err) <= limits + 1e-9, axis=1)
        if ok.any():
            return cands[ok]
        raise _not_controllable(goal, chain, cands[0], rots[0], err[0], jw[0], limits)
    sols = pose_ik(world.kin, tcp, chain, start, np.asarray(goal.position, float), goal_r,
                   limits=limits, position_tolerance=goal.tolerance)
    if not sols:
        raise GoalOutOfReach(
            f"no joint state within the limits reaches the pose (position "
            f"{list(goal.position)}, orientation {list(goal.orientation)} within "
            f"{[round(float(v), 6) for v in limits]} rad)",
            details={"position": list(goal.position), "orientation": list(goal.orientation),
                     "orientation_limits": limits.tolist(), "joints": list(ik_joints)})
    return _free_solutions(sols, world=world, what="the pose")


class ControllableAxis(TypedDict):
    """A world direction the chain turns the tool about, with the (parallel) joints that
    do, named when it is a world axis."""

    direction: list[float]
    joints: list[str]
    about: str


def controllable_axes(chain_names: Sequence[str], jw: np.ndarray
                      ) -> list[ControllableAxis]:
    """The axes (world directions) the chain's joints turn the tool about, parallel
    joints together: from the angular Jacobian ``jw`` (3, n) at a state."""
    groups: list[tuple[np.ndarray, list[str]]] = []
    for name, w in zip(chain_names, jw.T):
        n = float(np.linalg.norm(w))
        if n < 1e-9:
            continue  # a prismatic joint: it does not turn the tool
        u = w / n
        for axis, members in groups:
            if abs(abs(float(axis @ u)) - 1.0) < 1e-6:
                members.append(name)
                break
        else:
            groups.append((u, [name]))
    out: list[ControllableAxis] = []
    for axis, members in groups:
        named = next((lbl for lbl, e in (("world x", (1, 0, 0)), ("world y", (0, 1, 0)),
                                         ("world z", (0, 0, 1)))
                      if abs(abs(float(axis @ np.array(e, float))) - 1) < 1e-6), None)
        out.append({"direction": [round(float(v), 9) for v in axis], "joints": members,
                    "about": named or "the axis " + str([round(float(v), 3) for v in axis])})
    return out


def _not_controllable(goal: PoseGoal, chain: Chain, q: np.ndarray, rot: np.ndarray,
                      err: np.ndarray, jw: np.ndarray, limits: np.ndarray
                      ) -> OrientationNotControllable:
    names = tuple(chain.joint_names)
    axes = controllable_axes(names, jw)
    over = [a for a, e, b in zip(AXES, err, limits) if abs(e) > b + 1e-9]
    turns = "; ".join(f"about {a['about']} ({', '.join(a['joints'])})" for a in axes)
    return OrientationNotControllable(
        f"the group's {len(names)} joints ({', '.join(names)}) all go to placing the tcp "
        f"(position-only IK), so the tool's orientation follows from the position: they "
        f"turn it only {turns}, none of it independently of the position. At "
        f"{list(goal.position)} the tool is off the goal orientation by "
        f"{[round(float(v), 4) for v in err]} rad (rotation vector in the goal frame); "
        f"free axis {', '.join(over)} (free_axes) or give a position goal",
        controllable=axes,
        details={"joints": list(names), "orientation_dof": max(0, len(names) - 3),
                 "constrained_axes": list(goal.constrained), "exceeded_axes": over,
                 "reached": {"orientation": list(quaternion_of_matrix(rot)),
                             "rpy": list(rpy_of_matrix(rot)),
                             "q": [float(v) for v in q]},
                 "residuals": {"orientation": [float(v) for v in err]}})
