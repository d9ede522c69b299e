"""The gripper of a task: its planning group, the goal a gripper step names (a named
state, the leader's value, or the leader and its mimics), and the link that holds what it
picks up."""

from __future__ import annotations

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.planner.planning.goals import Goal, JointGoal, NamedGoal

#: the SRDF state names ``open`` and ``close`` stand for, first match wins (the
#: arduinobot's are gripper_open and gripper_closed; MoveIt configs often say open/close)
OPEN_NAMES = ("open", "gripper_open", "opened")
CLOSE_NAMES = ("close", "closed", "gripper_close", "gripper_closed")
MIMIC_TOLERANCE = 1e-6  # [rad] a mimic value must agree with its leader's within this



def gripper_group(description: Description) -> str:
    """The gripper's planning group: the SRDF end effector's, else a group ``gripper``.

    Raises:
        InvalidRequest: the robot has neither.
    """
    srdf = description.srdf
    if srdf is not None and srdf.end_effectors:
        return srdf.end_effectors[0].group
    if srdf is not None and "gripper" in srdf.groups:
        return "gripper"
    raise InvalidRequest("the robot has no gripper group (no SRDF end_effector, no group "
                         "'gripper')", field="gripper")


def gripper_goal(description: Description, command: str | float | tuple[float, ...],
                 group: str, *, where: str = "gripper") -> Goal:
    """The goal a gripper step's ``command`` names (see :class:`GripperStep`).

    Raises:
        InvalidRequest: an unknown state (naming the gripper's), a mimic value that
            disagrees with its leader's, more values than the leader and its mimics.
    """
    joints = description.group_joints().get(group, [])
    if not joints:
        raise InvalidRequest(f"the gripper group '{group}' moves no joint", field=where)
    leader = joints[0]
    if isinstance(command, str):
        srdf = description.srdf
        names = [s.name for s in (srdf.states if srdf is not None else ()) if s.group == group]
        wanted = {"open": OPEN_NAMES, "close": CLOSE_NAMES}.get(command, (command,))
        found = next((n for n in wanted if n in names), None)
        if found is None:
            raise InvalidRequest(f"'{command}' is no state of the group '{group}' (its "
                                 f"states: {', '.join(names) or 'none'})", field=where,
                                 details={"known": names})
        return NamedGoal(found)
    if isinstance(command, float):
        return JointGoal({leader: command}, where=where)
    robot = description.robot
    order = [leader, *robot.mimics_of(leader)]
    if len(command) > len(order):
        raise InvalidRequest(f"{len(command)} values for {', '.join(order)} (the leader "
                             "and its mimics)", field=where)
    for name, v in zip(order[1:], command[1:]):
        m = robot.joints[name].mimic
        assert m is not None  # mimics_of lists only mimics of the leader
        expected = m.multiplier * command[0] + m.offset
        if abs(v - expected) > MIMIC_TOLERANCE:
            raise InvalidRequest(f"{name} mimics {leader} ({name} = {m.multiplier:g} * "
                                 f"{leader} + {m.offset:g}): {leader}={command[0]:g} gives "
                                 f"{expected:g}, not {v:g}", field=where)
    return JointGoal({leader: command[0]}, where=where)


def holding_link(description: Description) -> str:
    """The link an attached object is held by without ``link``: the end effector's
    parent, else the tcp's."""
    srdf = description.srdf
    if srdf is not None and srdf.end_effectors:
        return srdf.end_effectors[0].parent_link
    if description.tcp is not None:
        return description.tcp.parent_link
    raise InvalidRequest("name the link that holds the object (the robot has no end "
                         "effector and no tcp)", field="link")
