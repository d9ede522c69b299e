"""Planning a task as a whole before anything moves.

Each step starts where the previous one ends, with the scene as the earlier steps leave
it: an attach step takes the obstacle out of the scene and makes it part of the robot
(:class:`~arduinobot.scene.obstacles.AttachedObject` on every later request's ``attached``), a detach
step puts it back where it then is. Arm steps plan for their group, gripper steps for
the gripper's (the SRDF end effector's group), each through the one door,
:meth:`~arduinobot.planner.planning.pipeline.MotionPlanner.solve`, so every step's trajectory is
certified and verified as any single plan is. The first step that fails stops the
task: :class:`TaskStepFailed` carries that step's own error (its code too) and its index.
An object attached where it rests on something (touching it: no gap) may touch it
until a motion ends with it clear (a lift): that pair is allowed for each motion step
until then (``Progress.resting``), and no longer.
A pick or a place step is expanded into these primitive steps by
:mod:`arduinobot.planner.tasks.pick` and :mod:`arduinobot.planner.tasks.place`, which
try their candidates through :class:`~arduinobot.planner.tasks.progress.Progress` until
one plans whole; every other step is :func:`~arduinobot.planner.tasks.progress.run_step`.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

from arduinobot.contract.errors import PlanningError
from arduinobot.planner.frames import RobotFrames
from arduinobot.planner.tasks.precheck import check_task
from arduinobot.planner.tasks.progress import Progress, run_step
from arduinobot.planner.tasks.results import TaskResult, TaskStepFailed
from arduinobot.planner.tasks.steps import (
    PickStep,
    PlaceStep,
    Task,
)

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
    # pick and place (claw meshes, grasps) are loaded by the first task that plans
    from arduinobot.planner.tasks.pick import plan_pick
    from arduinobot.planner.tasks.place import plan_place
    t_start = time.perf_counter()
    desc = planner.description
    check_task(task, desc)  # a typo in any step, before the first is planned
    names = planner.joint_names
    world = planner.world(())
    frames = RobotFrames(desc, kin=world.kin, bodies=world.bodies)  # attach, detach
    q = dict.fromkeys(names, 0.0)
    if task.start is not None:
        q.update({k: float(v) for k, v in task.start.items()})
    progress = Progress(planner, task, frames, q, list(task.obstacles),
                        attached=list(task.carrying), resting=set(task.resting))
    for i, step in enumerate(task.steps):
        try:
            if isinstance(step, PickStep):
                plan_pick(progress, step, i)
            elif isinstance(step, PlaceStep):
                plan_place(progress, step, i)
            else:
                run_step(progress, step, i)
        except PlanningError as e:
            _log.info("task %s: step %d (%s) failed: %s", task.name or "", i, step.kind,
                      e.message)
            raise TaskStepFailed(i, step, e, planned=tuple(progress.done)) from e
    done = progress.done
    return TaskResult(tuple(done), names, float(sum(s.duration for s in done)),
                      time.perf_counter() - t_start, tuple(progress.obstacles),
                      tuple(task.obstacles), tuple(progress.choices))
