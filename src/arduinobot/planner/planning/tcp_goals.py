"""Tcp position and pose goals resolved to joint states by inverse kinematics.

A tcp position resolves to every collision-free IK solution, so the planner may reach
whichever is easiest; with a tolerance, to solutions for points inside its sphere where
the exact position has none.

A pose goal (a position and an orientation) is planned only for a group whose joints can
choose the tcp's orientation; for a position-only group (the arduinobot's three joints)
one whose orientation the position does not already give is refused with
:class:`~arduinobot.contract.errors.OrientationNotControllable`, naming the axes the group turns the
tool about, never answered with a different orientation.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from arduinobot.contract.errors import (
    GoalInCollision,
    GoalOutOfReach,
    InvalidRequest,
    OrientationNotControllable,
)
from arduinobot.description import Description, Tcp
from arduinobot.description.model import rpy_of
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.rotations import (
    matrix_of_quaternion,
    quaternion_of_matrix,
    rotation_error,
)
from arduinobot.planner.planning.goals import AXES, PoseGoal, PositionGoal

if TYPE_CHECKING:
    from arduinobot.planner.kinematics.ik import IkSolution
    from arduinobot.planner.kinematics.ik_numeric import Chain


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


def _sphere_points(center: np.ndarray, radius: float) -> np.ndarray:
    # the 26 directions of a cube's faces, edges and corners, at the radius and half
    dirs = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], float) - 1.0
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    return np.concatenate([center + radius * dirs, center + 0.5 * radius * dirs])


def position_candidates(goal: PositionGoal | PoseGoal, *, world: CollisionWorld,
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
    from arduinobot.planner.kinematics.ik import (
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


def pose_candidates(goal: PoseGoal, *, world: CollisionWorld, description: Description,
                     start: np.ndarray, group_joints: Sequence[str]) -> np.ndarray:
    """Collision-free states reaching the pose within its tolerances.

    A position-only chain (at most three joints move the tcp) keeps the IK states of the
    position whose orientation is already within the goal's tolerances; when none is,
    :class:`OrientationNotControllable` names the axes the chain turns the tool about.
    """
    from arduinobot.planner.kinematics.ik_numeric import build_chain
    from arduinobot.planner.kinematics.ik_pose import pose_ik, tool_jacobian

    tcp = _tcp(description)
    ik_joints = tcp_joints(description, group_joints)
    chain = build_chain(world.kin, tcp, ik_joints)
    goal_r = matrix_of_quaternion(goal.orientation)
    limits = goal.limits
    if len(ik_joints) <= POSITION_JOINTS:
        cands = position_candidates(goal, world=world, description=description,
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
        raise _pose_out_of_reach(goal, ik_joints, limits)
    return _free_solutions(sols, world=world, what="the pose")


def _pose_out_of_reach(goal: PoseGoal, ik_joints: Sequence[str], limits: np.ndarray
                       ) -> GoalOutOfReach:
    """No IK state reaches the pose. With fewer than six joints and more orientation
    axes held than the joints beyond three can set, that is the likely reason: say so
    and suggest ``free_axes`` (a 5-joint arm sets the position and two axes)."""
    n, held = len(ik_joints), list(goal.constrained)
    can = max(0, n - POSITION_JOINTS)
    pos = [round(float(v), 4) for v in goal.position]
    quat = [round(float(v), 4) for v in goal.orientation]
    why = ""
    if n < 6 and len(held) > can:
        free = [a for a in AXES if a in held][-(len(held) - can):]
        why = (f": the group's {n} joints ({', '.join(ik_joints)}) set the position and at "
               f"most {can} of the tool's rotation axes, and the goal holds {len(held)} "
               f"({', '.join(held)}); free {len(held) - can} with free_axes (e.g. "
               f"\"free_axes\": {json.dumps(free)}: a tool pointing down, free to turn "
               "about its own axis) or give a position goal")
    return GoalOutOfReach(
        f"no joint state within the limits reaches the pose (position {pos}, orientation "
        f"{quat} within {[round(float(v), 4) for v in limits]} rad){why}",
        details={"position": list(goal.position), "orientation": list(goal.orientation),
                 "orientation_limits": limits.tolist(), "joints": list(ik_joints),
                 "constrained_axes": held, "orientation_dof": can,
                 **({"suggest_free_axes": free} if why else {})})


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
                             "rpy": list(rpy_of(rot)),
                             "q": [float(v) for v in q]},
                 "residuals": {"orientation": [float(v) for v in err]}})
