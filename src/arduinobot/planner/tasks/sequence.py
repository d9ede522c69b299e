"""Planning a task as a whole before anything moves.

Each step starts where the previous one ends, with the scene as the earlier steps leave
it: an attach step takes the obstacle out of the scene and makes it part of the robot
(:class:`~arduinobot.scene.obstacles.AttachedObject` on every later request's ``attached``), a detach
step puts it back where it then is. Arm steps plan for their group, gripper steps for
the gripper's (the SRDF end effector's group), each through the one door,
:meth:`~arduinobot.planner.planning.pipeline.MotionPlanner.solve`, so every step's trajectory is
certified and verified as any single plan is. The first step that fails stops the
task: :class:`TaskStepFailed` carries that step's own error (its code too) and its index.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.planner.frames import RobotFrames
from arduinobot.planner.planning.goals import Goal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.planner.planning.pathfinding.search import MAX_SEED
from arduinobot.planner.tasks.gripper import gripper_goal, gripper_group, holding_link
from arduinobot.planner.tasks.precheck import check_task
from arduinobot.planner.tasks.results import StepResult, TaskResult, TaskStepFailed
from arduinobot.planner.tasks.steps import (
    AttachStep,
    DetachStep,
    GripperStep,
    MotionOptions,
    MoveStep,
    Task,
    WaitStep,
)
from arduinobot.scene.frames import attach, detach
from arduinobot.scene.obstacles import AttachedObject, Obstacle

if TYPE_CHECKING:  # the service imports this module before it plans anything
    from arduinobot.planner.planning.pipeline import MotionPlanner

_log = logging.getLogger(__name__)

def plan_task(planner: MotionPlanner, task: Task) -> TaskResult:
    """Plan every step of ``task`` in order, nothing executed.

    Raises:
        TaskStepFailed: the first step that fails, with its own error and code (a name
            the robot or the task lacks, in any step, before any is planned).
        InvalidRequest: the task's start (names, limits) is invalid.
    """
    t_start = time.perf_counter()
    desc = planner.description
    check_task(task, desc)  # a typo in any step, before the first is planned
    names = planner.joint_names
    world = planner.world(())
    frames = RobotFrames(desc, kin=world.kin, bodies=world.bodies)  # attach, detach
    q = dict.fromkeys(names, 0.0)
    if task.start is not None:
        q.update({k: float(v) for k, v in task.start.items()})
    obstacles = list(task.obstacles)
    attached: list[AttachedObject] = []
    done: list[StepResult] = []
    held: tuple[str | None, str | None] = (None, None)  # an attach/detach step's object, link

    def vec(state: Mapping[str, float]) -> np.ndarray:
        return np.array([state[n] for n in names], float)

    for i, step in enumerate(task.steps):
        try:
            start = dict(q)
            if isinstance(step, (MoveStep, GripperStep)):
                if isinstance(step, GripperStep):
                    group: str | None = gripper_group(desc)
                    goal = gripper_goal(desc, step.command, group,  # type: ignore[arg-type]
                                        where=f"steps[{i}].gripper")
                else:
                    group, goal = step.group, step.goal
                req = _request(task, step.options, goal, group, start, obstacles, attached, i)
                res = planner.solve(req)
                tr = res.trajectory
                q = {n: float(v) for n, v in zip(tr.joint_names, tr.positions[-1])}
                done.append(StepResult(i, step.kind, step.label, start, dict(q),
                                       float(tr.duration), res,
                                       tuple(a.id for a in attached), group))
                continue
            if isinstance(step, AttachStep):
                k = next((j for j, o in enumerate(obstacles) if o.id == step.object), None)
                if k is None:
                    raise InvalidRequest(
                        f"no obstacle '{step.object}' in the scene to attach (obstacles: "
                        f"{', '.join(o.id for o in obstacles) or 'none'})",
                        field=f"steps[{i}].attach")
                link = step.link or holding_link(desc)
                attached.append(attach(frames, obstacles[k], link, vec(q),
                                       touch_links=step.touch_links, mass=step.mass,
                                       where=f"steps[{i}].attach",
                                       **({} if step.reach is None else
                                          {"reach": step.reach})))
                obstacles.pop(k)
                held = (step.object, link)
            elif isinstance(step, DetachStep):
                k = next((j for j, a in enumerate(attached) if a.id == step.object), None)
                if k is None:
                    raise InvalidRequest(
                        f"the robot carries no '{step.object}' (carried: "
                        f"{', '.join(a.id for a in attached) or 'nothing'})",
                        field=f"steps[{i}].detach")
                carried = attached.pop(k)
                obstacles.append(detach(frames, carried, vec(q), where=f"steps[{i}].detach"))
                held = (step.object, carried.link)
            done.append(StepResult(i, step.kind, step.label, start, dict(q),
                                   step.seconds if isinstance(step, WaitStep) else 0.0,
                                   None, tuple(a.id for a in attached), object=held[0],
                                   link=held[1]))
            held = (None, None)
        except PlanningError as e:
            _log.info("task %s: step %d (%s) failed: %s", task.name or "", i, step.kind,
                      e.message)
            raise TaskStepFailed(i, step, e, planned=tuple(done)) from e
    return TaskResult(tuple(done), names, float(sum(s.duration for s in done)),
                      time.perf_counter() - t_start, tuple(obstacles), tuple(task.obstacles))


def _request(task: Task, options: MotionOptions, goal: Goal, group: str | None,
             start: Mapping[str, float], obstacles: list[Obstacle],
             attached: list[AttachedObject], index: int) -> MotionRequest:
    return MotionRequest(
        goal=goal, start=dict(start), group=group, obstacles=tuple(obstacles),
        attached=tuple(attached), clouds=task.clouds, ground=task.ground,
        planning_time=options.planning_time or task.planning_time,
        velocity_scaling=options.velocity_scaling or task.velocity_scaling,
        acceleration_scaling=options.acceleration_scaling or task.acceleration_scaling,
        # each motion its own seed, in the seeds' range
        seed=None if task.seed is None else (task.seed + index) % (MAX_SEED + 1))
