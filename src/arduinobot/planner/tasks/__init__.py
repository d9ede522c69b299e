"""Tasks: an ordered list of steps (move, line, gripper, attach, detach, wait) planned as
a whole before anything moves (:mod:`.steps` the model, :mod:`.sequence` the planning,
:mod:`.precheck` the names checked before planning; the named tasks of a ``tasks.yaml``
are read by :func:`arduinobot.description.moveit_config.read_tasks`)."""

from arduinobot.planner.tasks.sequence import StepResult, TaskResult, TaskStepFailed, plan_task
from arduinobot.planner.tasks.steps import (
    AttachStep,
    DetachStep,
    GripperStep,
    MoveStep,
    Step,
    Task,
    WaitStep,
    task_from_mapping,
)

__all__ = ["AttachStep", "DetachStep", "GripperStep", "MoveStep", "Step", "StepResult",
           "Task", "TaskResult", "TaskStepFailed", "WaitStep", "plan_task",
           "task_from_mapping"]
