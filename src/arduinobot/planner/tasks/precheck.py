"""A task's names checked against the robot before any step is planned: a typo in step
7 is reported in milliseconds, not after steps 0-6 took seconds to plan.

What can be known without planning is checked here: each motion step's group, the
joints of a joint goal, the named state of a named goal or a gripper step, an attach's
object (among the task's obstacles, as attach and detach steps before it leave them)
and link, a detach's object, a pick's object, a place's object and where it goes (a
place of the task's or an obstacle). Reachability, collisions and limits stay the planner's.
"""

from __future__ import annotations

from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.description import Description
from arduinobot.description.errors import SrdfError
from arduinobot.planner.planning.goals import JointGoal, NamedGoal
from arduinobot.planner.tasks.gripper import gripper_goal, gripper_group
from arduinobot.planner.tasks.results import TaskStepFailed
from arduinobot.planner.tasks.steps import (
    AttachStep,
    DetachStep,
    GripperStep,
    MoveStep,
    PickStep,
    PlaceStep,
    Task,
)


def check_task(task: Task, description: Description) -> None:
    """Refuse a task whose steps name what the robot or the task does not have.

    Raises:
        TaskStepFailed: the first such step, with its InvalidRequest naming the field
            (``planned_steps`` 0: nothing was planned).
    """
    groups = description.group_joints()
    actuated = set(description.robot.actuated_joints)
    links = description.robot.links
    free = {o.id for o in task.obstacles}
    carried: set[str] = {a.id for a in task.carrying}
    for i, step in enumerate(task.steps):
        where = f"steps[{i}]"
        try:
            if isinstance(step, MoveStep):
                _check_move(step, description, groups, actuated, where)
            elif isinstance(step, GripperStep):
                gripper_goal(description, step.command, gripper_group(description),
                             where=f"{where}.gripper")
            elif isinstance(step, PickStep):
                if step.object not in free:
                    raise InvalidRequest(
                        f"no obstacle '{step.object}' in the scene to pick (obstacles "
                        f"then: {', '.join(sorted(free)) or 'none'})", field=f"{where}.pick")
                free.discard(step.object)
                carried.add(step.object)
            elif isinstance(step, PlaceStep):
                if step.object not in carried:
                    raise InvalidRequest(
                        f"the robot carries no '{step.object}' then to place (carried: "
                        f"{', '.join(sorted(carried)) or 'nothing'})", field=f"{where}.place")
                at = step.at
                named = at.name if at.name is not None else at.on
                if named is not None and named not in task.places and named not in free:
                    raise InvalidRequest(
                        f"'{named}' is no place of the task (places: "
                        f"{', '.join(task.places) or 'none'}) and no obstacle then "
                        f"(obstacles: {', '.join(sorted(free)) or 'none'})",
                        field=f"{where}.at")
                carried.discard(step.object)
                free.add(step.object)
            elif isinstance(step, AttachStep):
                if step.object not in free:
                    raise InvalidRequest(
                        f"no obstacle '{step.object}' in the scene to attach (obstacles "
                        f"then: {', '.join(sorted(free)) or 'none'})", field=f"{where}.attach")
                if step.link is not None and step.link not in links:
                    raise InvalidRequest(f"'{step.link}' is not a link of the robot",
                                         field=f"{where}.link")
                free.discard(step.object)
                carried.add(step.object)
            elif isinstance(step, DetachStep):
                if step.object not in carried:
                    raise InvalidRequest(
                        f"the robot carries no '{step.object}' then (carried: "
                        f"{', '.join(sorted(carried)) or 'nothing'})", field=f"{where}.detach")
                carried.discard(step.object)
                free.add(step.object)
        except PlanningError as e:
            raise TaskStepFailed(i, step, e) from e


def _check_move(step: MoveStep, description: Description, groups: dict[str, list[str]],
                actuated: set[str], where: str) -> None:
    if step.group is not None and step.group not in groups:
        raise InvalidRequest(f"'{step.group}' is not a group of this robot (groups: "
                             f"{', '.join(groups)})", field=f"{where}.group")
    goal = step.goal
    if isinstance(goal, JointGoal):
        unknown = [n for n in goal.values if n not in actuated]
        if unknown:
            raise InvalidRequest(f"{', '.join(unknown)}: not an actuated joint of the robot "
                                 f"(joints: {', '.join(description.robot.actuated_joints)})",
                                 field=f"{where}.move.joints")
    elif isinstance(goal, NamedGoal):
        srdf = description.srdf
        if srdf is None:
            raise InvalidRequest("the model has no SRDF, so no named states",
                                 field=f"{where}.move.named")
        group = None if step.group in (None, "all") else step.group
        try:
            srdf.named_state(goal.name, group)
        except SrdfError as e:
            raise InvalidRequest(e.message + (f" ({e.hint})" if e.hint else ""),
                                 field=f"{where}.move.named") from None
