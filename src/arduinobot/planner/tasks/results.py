"""What planning a task gives: each step's result, the whole task's, and the failure of a
step (which carries that step's own error and code)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.contract.errors import PlanningError
from arduinobot.planner.planning.motion import MotionResult
from arduinobot.planner.tasks.steps import Step, StepKind
from arduinobot.scene.obstacles import AttachedObject, Obstacle


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
    # the task's pick or place step this one was generated for (None: the task's own)
    part_of: int | None = None
    # attach: what the object is held with, its touch links, and its mass [kg]
    touch_links: tuple[str, ...] = ()
    mass: float = 0.0
    # the world the step was planned in (a motion step) or leaves (attach, detach, wait):
    # the objects carried, posed on their links; the scene's obstacles as the task had
    # them; the (object, obstacle) pairs allowed to touch (a resting object, the claw's)
    attached: tuple[AttachedObject, ...] = ()
    obstacles: tuple[Obstacle, ...] = ()
    allowed: tuple[tuple[str, str], ...] = ()


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
    #: what each pick and place step chose (sequence.Choice)
    choices: tuple[Any, ...] = ()

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
