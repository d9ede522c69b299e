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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.description import Description
from arduinobot.planner.frames import RobotFrames
from arduinobot.planner.planning.goals import Goal, JointGoal, NamedGoal
from arduinobot.planner.planning.motion import MotionRequest, MotionResult
from arduinobot.planner.planning.search import MAX_SEED
from arduinobot.planner.tasks.precheck import check_task
from arduinobot.planner.tasks.steps import (
    AttachStep,
    DetachStep,
    GripperStep,
    MotionOptions,
    MoveStep,
    Step,
    StepKind,
    Task,
    WaitStep,
)
from arduinobot.scene.frames import attach, detach
from arduinobot.scene.obstacles import AttachedObject, Obstacle

if TYPE_CHECKING:  # the service imports this module before it plans anything
    from arduinobot.planner.planning.pipeline import MotionPlanner

_log = logging.getLogger(__name__)

#: the SRDF state names ``open`` and ``close`` stand for, first match wins (the
#: arduinobot's are gripper_open and gripper_closed; MoveIt configs often say open/close)
OPEN_NAMES = ("open", "gripper_open", "opened")
CLOSE_NAMES = ("close", "closed", "gripper_close", "gripper_closed")
MIMIC_TOLERANCE = 1e-6  # [rad] a mimic value must agree with its leader's within this


@dataclass(frozen=True)
class StepResult:
    """One planned step: its joint state [rad] at start and end, its duration [s], its
    verified trajectory (None for attach, detach, wait) and the objects the robot
    carries at its end (while it ran, for a motion step)."""

    index: int
    kind: StepKind
    label: str | None
    start: Mapping[str, float]
    end: Mapping[str, float]
    duration: float
    result: MotionResult | None
    carried: tuple[str, ...]
    group: str | None = None
    # attach, detach: the object and the link that holds it
    object: str | None = None
    link: str | None = None


@dataclass(frozen=True)
class TaskResult:
    """Every step planned, in order; ``duration`` the task's [s] (the sum of the steps');
    ``planning_time`` the seconds planning took."""

    steps: tuple[StepResult, ...]
    joint_names: tuple[str, ...]
    duration: float
    planning_time: float
    obstacles: tuple[Obstacle, ...]  # the scene as the last step leaves it
    start_obstacles: tuple[Obstacle, ...] = ()  # the scene the task starts in

    def boundaries(self) -> list[float]:
        """Each step's start time in the task [s]."""
        out, t = [], 0.0
        for s in self.steps:
            out.append(t)
            t += s.duration
        return out

    def samples(self, sample_rate: float = 100.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The whole task as one sampled trajectory: times [s] shape (m,), positions,
        velocities, accelerations shape (m, dof) in ``joint_names`` order; a wait step
        holds the last state at ``sample_rate``. Each step ends at rest, so joining them
        keeps every limit each step was verified against."""
        dof = len(self.joint_names)
        ts, qs, qds, qdds = [np.zeros(1)], [], [], []
        q_last = np.array([self.steps[0].start[n] for n in self.joint_names], float)
        qs.append(q_last[None])
        qds.append(np.zeros((1, dof)))
        qdds.append(np.zeros((1, dof)))
        t0 = 0.0
        for s in self.steps:
            if s.result is not None:
                tr = s.result.trajectory
                idx = [tr.joint_names.index(n) for n in self.joint_names]
                times = np.asarray(tr.times, float)
                keep = times > 1e-12  # the first sample is where the last step ended
                ts.append(t0 + times[keep])
                qs.append(np.asarray(tr.positions, float)[keep][:, idx])
                qds.append(np.asarray(tr.velocities, float)[keep][:, idx])
                qdds.append(np.asarray(tr.accelerations, float)[keep][:, idx])
                if keep.any():  # a step already at its goal has its start sample only
                    q_last = qs[-1][-1]
            elif s.duration > 0:
                n = max(1, int(round(s.duration * sample_rate)))
                ts.append(t0 + np.linspace(s.duration / n, s.duration, n))
                qs.append(np.repeat(q_last[None], n, axis=0))
                qds.append(np.zeros((n, dof)))
                qdds.append(np.zeros((n, dof)))
            t0 += s.duration
        return (np.concatenate(ts), np.concatenate(qs), np.concatenate(qds),
                np.concatenate(qdds))


class TaskStepFailed(PlanningError):
    """Step ``index`` of the task could not be planned; ``error`` is its own error,
    whose code this one carries (a line through the table stays LINE_INTERRUPTED), so a
    client handles it as that step's failure. ``planned``: the steps before it."""

    def __init__(self, index: int, step: Step, error: PlanningError, *,
                 planned: tuple[StepResult, ...] = ()) -> None:
        self.index, self.step, self.error, self.planned = index, step, error, planned
        self.code = error.code
        name = f"step {index} ({step.kind}{', ' + step.label if step.label else ''})"
        super().__init__(f"{name}: {error.message}", details={
            "step": index, "kind": step.kind, "label": step.label,
            "error": {"code": str(error.code), "message": error.message,
                      "details": dict(error.details)},
            "planned_steps": len(planned)})


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
                                       where=f"steps[{i}].attach"))
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
        attached=tuple(attached), clouds=task.clouds,
        planning_time=options.planning_time or task.planning_time,
        velocity_scaling=options.velocity_scaling or task.velocity_scaling,
        acceleration_scaling=options.acceleration_scaling or task.acceleration_scaling,
        # each motion its own seed, in the seeds' range
        seed=None if task.seed is None else (task.seed + index) % (MAX_SEED + 1))
