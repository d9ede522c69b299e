"""Tasks: an ordered list of steps (move, line, gripper, attach, detach, wait, pick,
place) planned as a whole before anything moves. The named tasks of a ``tasks.yaml`` are read by
:func:`arduinobot.description.moveit_config.read_tasks`.

- ``steps``: the model (a task, its steps).
- ``task_json``: a task read from its JSON (or YAML) form, a bad field named.
- ``precheck``: the names a task's steps use, checked before anything is planned.
- ``sequence``: the planning, step after step through the one door.
- ``progress``: the planning so far, and one primitive step planned from there.
- ``results``: what it gives (each step's result, the task's) and a step's failure.
- ``gripper``: the gripper's group, the goal a gripper step names, the holding link.
- ``claw``: the claw's fingertips: their gap over the gripper's range, their midpoint.
- ``grasps``: a pick's candidates from the object's shape, only those the arm reaches.
- ``pick``: a pick step expanded into primitive steps, candidates tried until one plans.
- ``place``: a place step expanded the same way, over the free spots.
- ``places``: supports an object rests on, named places, spots on a support.
"""

from arduinobot.planner.tasks.results import StepResult, TaskResult, TaskStepFailed
from arduinobot.planner.tasks.sequence import plan_task
from arduinobot.planner.tasks.steps import (
    AttachStep,
    DetachStep,
    GripperStep,
    MoveStep,
    PickStep,
    PlaceStep,
    PlaceTarget,
    Step,
    Task,
    WaitStep,
)
from arduinobot.planner.tasks.task_json import task_from_mapping

__all__ = ["AttachStep", "DetachStep", "GripperStep", "MoveStep", "PickStep", "PlaceStep",
           "PlaceTarget", "Step", "StepResult",
           "Task", "TaskResult", "TaskStepFailed", "WaitStep", "plan_task",
           "task_from_mapping"]
