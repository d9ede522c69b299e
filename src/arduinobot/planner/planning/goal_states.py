"""Goals resolved to joint states: the planning group of a request, named states, joint
goals (with their tolerances), and the dispatch to :mod:`arduinobot.planner.planning.tcp_goals` for
tcp positions and poses.

Each goal resolves to one or more full joint vectors, collision-free and within the
limits; joints outside the group keep their start value.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence

import numpy as np

from arduinobot.contract.errors import GoalInCollision, InvalidRequest, PlanningError
from arduinobot.description import Description
from arduinobot.description.errors import SrdfError
from arduinobot.planner.checks import check_joint_names, check_positions
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import Goal, JointGoal, LineGoal, NamedGoal, PoseGoal
from arduinobot.planner.planning.tcp_goals import pose_candidates, position_candidates


def resolve_group(description: Description, group: str | None, goal: Goal) -> str:
    """The planning group of a request: ``group`` if given (it must exist); for a named
    goal, the group that defines the state; else the description's default group.

    Raises:
        InvalidRequest: an unknown group (naming the known ones), or a named state that
            several groups define when no group was given (naming them).
    """
    srdf = description.srdf
    known = tuple(description.group_joints())  # the groups a request may name, "all" too
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


def check_limits(world: CollisionWorld, q: np.ndarray, *, field: str) -> None:
    """Raise :class:`JointLimitViolation` naming the first joint outside its limits."""
    names = world.kin.joint_names
    check_positions(names, q, world.description.robot.position_limits(names), field=field)


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
        return pose_candidates(goal, world=world, description=description, start=start,
                                group_joints=group_joints)
    if isinstance(goal, LineGoal):
        raise InvalidRequest("a line is planned by the straight-line strategy, not "
                             "resolved to goal states", field="goal.line")
    # a PositionGoal: the request checked the goal's type when it was built (check_goal)
    return position_candidates(goal, world=world, description=description, start=start,
                                group_joints=group_joints)


def _within_joint_tolerances(goal: JointGoal, q: np.ndarray, *, world: CollisionWorld,
                             idx: Mapping[str, int]) -> np.ndarray:
    """Collision-free states within the limits and the goal's tolerances, nearest the
    exact goal first (each tolerant joint at -tol, -tol/2, 0, tol/2, tol); raises the
    exact goal's error when there is none."""
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
