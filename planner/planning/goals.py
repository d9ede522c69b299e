"""Planning goals: joint values, named SRDF states and tcp positions.

Each goal resolves to one or more full joint vectors; a tcp position resolves to every
collision-free IK solution, so the planner may reach whichever is easiest.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from description import Description, Tcp
from description.errors import SrdfError

from ..checks import check_joint_names, check_positions
from ..collision.world import CollisionWorld
from ..errors import GoalInCollision, GoalOutOfReach, InvalidRequest


@dataclass(frozen=True)
class JointGoal:
    """Target values [rad] for some or all joints of the group; the rest keep their start.
    ``where`` names the values in errors (the service's requests: ``goal.joints``)."""

    values: Mapping[str, float]
    where: str = field(default="goal.values", repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.values, Mapping) or not self.values:
            raise InvalidRequest("needs at least one joint value", field=self.where)
        for k, v in self.values.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InvalidRequest(f"{v!r} is not a finite number [rad]",
                                     field=f"{self.where}.{k}")
        object.__setattr__(self, "values", dict(self.values))


@dataclass(frozen=True)
class NamedGoal:
    """A named state from the SRDF (``home``, ``reach_forward``, ...)."""

    name: str


@dataclass(frozen=True)
class PositionGoal:
    """A tcp position [m] in the world frame, shape (3,)."""

    position: tuple[float, float, float]
    where: str = field(default="goal.position", repr=False)

    def __post_init__(self) -> None:
        try:
            p = tuple(float(v) for v in self.position)
        except (TypeError, ValueError):
            p = ()
        if len(p) != 3 or not all(math.isfinite(v) for v in p):
            raise InvalidRequest(f"{self.position!r} must be 3 finite numbers [m]",
                                 field=self.where)
        object.__setattr__(self, "position", p)


Goal = JointGoal | NamedGoal | PositionGoal


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
    if not isinstance(goal, (JointGoal, NamedGoal, PositionGoal)):
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
        check_limits(world, q, field=goal.where)
        chk = world.check(q)
        if not chk.valid:
            raise GoalInCollision("the goal state collides", pairs=chk.pairs,
                                  q=dict(zip(names, map(float, q))))
        return q[None]
    # a PositionGoal: the request checked the goal's type when it was built (check_goal)
    return _position_candidates(goal, world=world, description=description, start=start,
                                group_joints=group_joints)


def _position_candidates(goal: PositionGoal, *, world: CollisionWorld,
                         description: Description, start: np.ndarray,
                         group_joints: Sequence[str]) -> np.ndarray:
    from ..kinematics.ik import (
        position_ik,  # written alongside; imported late to keep startup light
    )

    ik_joints = tcp_joints(description, group_joints)
    sols = position_ik(world.kin, _tcp(description), goal.position, joints=ik_joints,
                       q_fixed=start)
    if not sols:
        raise GoalOutOfReach(f"no joint state reaches {goal.position}",
                             details={"position": list(goal.position)})
    free, first_pairs = [], None
    for s in sols:
        chk = world.check(s.q)
        if chk.valid:
            free.append(np.asarray(s.q, float))
        elif first_pairs is None:
            first_pairs = chk.pairs
    if not free:
        raise GoalInCollision(f"every IK solution ({len(sols)}) for {goal.position} collides",
                              pairs=first_pairs or ())
    return np.array(free)
