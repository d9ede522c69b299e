"""The planning of a task so far, and one primitive step planned from there.

:class:`Progress` holds the state the next step starts in, the scene as the steps so
far leave it (an attach step takes the obstacle out of the scene and makes it part of
the robot, :class:`~arduinobot.scene.obstacles.AttachedObject` on every later request's
``attached``; a detach step puts it back where it then is), the steps planned and the
candidates pick and place chose. :func:`run_step` plans one primitive step through the
one door, :meth:`~arduinobot.planner.planning.pipeline.MotionPlanner.solve`. An object
attached where it rests on something (touching it: no gap) may touch it until a motion
ends with it clear (a lift): that pair is allowed for each motion step until then
(:attr:`Progress.resting`), and no longer.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.planner.frames import RobotFrames
from arduinobot.planner.planning.goals import Goal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.planner.planning.pathfinding.search import MAX_SEED
from arduinobot.planner.planning.resting import cores_for
from arduinobot.planner.tasks.gripper import gripper_goal, gripper_group, holding_link
from arduinobot.planner.tasks.places import touching
from arduinobot.planner.tasks.results import StepResult
from arduinobot.planner.tasks.steps import (
    AttachStep,
    DetachStep,
    GripperStep,
    MotionOptions,
    MoveStep,
    Step,
    Task,
    WaitStep,
)
from arduinobot.scene.frames import attach, detach
from arduinobot.scene.ground import with_ground
from arduinobot.scene.obstacles import AttachedObject, Obstacle

if TYPE_CHECKING:  # the service imports this module before it plans anything
    from arduinobot.planner.planning.pipeline import MotionPlanner

_log = logging.getLogger(__name__)

#: a primitive step and the (object, obstacle) pairs allowed to touch while it runs
Part = tuple[Step, tuple[tuple[str, str], ...]]


@dataclass(frozen=True)
class Choice:
    """What a pick or place step chose: its task step ``index``, the ``object``, the
    candidate's ``name``, how many candidates were ``tried`` (planned or refused) of
    how many there were (``candidates``)."""

    index: int
    kind: str
    object: str
    name: str
    tried: int
    candidates: int
    details: Mapping[str, Any] = field(default_factory=dict)


@dataclass
class Progress:
    """The planning so far: the state [rad] the next step starts in, the scene as the
    steps so far leave it, what the robot carries, the steps planned, and the
    candidates each pick and place chose (each motion's seed is the task's plus its
    place in the planned list)."""

    planner: MotionPlanner
    task: Task
    frames: RobotFrames
    q: dict[str, float]
    obstacles: list[Obstacle]
    attached: list[AttachedObject] = field(default_factory=list)
    done: list[StepResult] = field(default_factory=list)
    choices: list[Choice] = field(default_factory=list)
    #: (carried object, obstacle) pairs touching since the attach, not yet cleared
    resting: set[tuple[str, str]] = field(default_factory=set)

    def vec(self, state: Mapping[str, float] | None = None) -> np.ndarray:
        s = self.q if state is None else state
        return np.array([s[n] for n in self.planner.joint_names], float)

    def obstacle_index(self, ident: str, *, to: str, field: str) -> int:
        """The index of the obstacle ``ident`` in :attr:`obstacles`.

        Raises:
            InvalidRequest: (``field``) no such obstacle: the ones there are named, and
                what it was wanted ``to`` do (pick, attach).
        """
        k = next((j for j, o in enumerate(self.obstacles) if o.id == ident), None)
        if k is None:
            raise InvalidRequest(
                f"no obstacle '{ident}' in the scene to {to} (obstacles: "
                f"{', '.join(o.id for o in self.obstacles) or 'none'})", field=field)
        return k

    def carried_index(self, ident: str, *, to: str | None = None, field: str) -> int:
        """The index of the carried object ``ident`` in :attr:`attached`.

        Raises:
            InvalidRequest: (``field``) the robot carries no such object: what it carries
                is named.
        """
        k = next((j for j, a in enumerate(self.attached) if a.id == ident), None)
        if k is None:
            raise InvalidRequest(
                f"the robot carries no '{ident}'{'' if to is None else ' to ' + to} "
                f"(carried: {', '.join(a.id for a in self.attached) or 'nothing'})",
                field=field)
        return k

    def snapshot(self) -> tuple:
        return (dict(self.q), list(self.obstacles), list(self.attached), len(self.done),
                set(self.resting))

    def restore(self, snap: tuple) -> None:
        q, obstacles, attached, n, resting = snap
        self.q, self.obstacles, self.attached = dict(q), list(obstacles), list(attached)
        del self.done[n:]
        self.resting = set(resting)

    def still_resting(self) -> None:
        """Drop the resting pairs whose object has come clear of its support (further
        than :data:`arduinobot.planner.tasks.places.TOUCHING`): from the next motion on
        the pair is checked again."""
        if not self.resting:
            return
        q = self.vec()
        for a in self.attached:
            pairs = {r for r in self.resting if r[0] == a.id}
            if not pairs:
                continue
            here = detach(self.frames, a, q)
            touched = set(touching(here, self.obstacles, ground=self.task.ground))
            self.resting -= {r for r in pairs if r[1] not in touched}

    def run(self, parts: Sequence[Part], index: int) -> None:
        """Plan ``parts`` in order (primitive steps of the task's step ``index``); the
        first that fails raises its own error (the progress then holds the ones
        before it: :meth:`restore` to undo)."""
        for step, allowed in parts:
            run_step(self, step, index, allowed=allowed, part_of=index)

def run_step(progress: Progress, step: Step, index: int, *,
             allowed: tuple[tuple[str, str], ...] = (), part_of: int | None = None) -> None:
    """Plan one primitive step from where ``progress`` is, and record it there."""
    p = progress
    desc, task = p.planner.description, p.task
    start = dict(p.q)
    at = len(p.done)  # the step's place in the planned list
    where = f"steps[{index}]"
    if isinstance(step, (MoveStep, GripperStep)):
        if isinstance(step, GripperStep):
            group: str | None = gripper_group(desc)
            goal = gripper_goal(desc, step.command, group,  # type: ignore[arg-type]
                                where=f"{where}.gripper")
        else:
            group, goal = step.group, step.goal
        pairs = tuple(sorted(set(allowed) | p.resting))
        cores, core_pairs = _cores(p, pairs)
        req = _request(task, step.options, goal, group, start, [*p.obstacles, *cores],
                       p.attached, at, allowed=pairs + core_pairs)
        res = p.planner.solve(req)
        tr = res.trajectory
        p.q = {n: float(v) for n, v in zip(tr.joint_names, tr.positions[-1])}
        p.done.append(StepResult(at, step.kind, step.label, start, dict(p.q),
                                 float(tr.duration), res, tuple(a.id for a in p.attached),
                                 group, part_of=part_of, attached=tuple(p.attached),
                                 obstacles=tuple(p.obstacles), allowed=pairs))
        p.still_resting()
        return
    held: tuple[str | None, str | None] = (None, None)
    touch: tuple[str, ...] = ()
    mass = 0.0
    if isinstance(step, AttachStep):
        k = p.obstacle_index(step.object, to="attach", field=f"{where}.attach")
        link = step.link or holding_link(desc)
        # what it rests on may touch it until a motion takes it clear (a lift)
        p.resting |= {(step.object, s) for s in touching(
            p.obstacles[k], [o for o in p.obstacles if o.id != step.object],
            ground=task.ground)}
        p.attached.append(attach(p.frames, p.obstacles[k], link, p.vec(),
                                 touch_links=step.touch_links, mass=step.mass,
                                 where=f"{where}.attach",
                                 **({} if step.reach is None else {"reach": step.reach})))
        p.obstacles.pop(k)
        held = (step.object, link)
        touch, mass = step.touch_links, step.mass  # as given (the twin resolves them)
    elif isinstance(step, DetachStep):
        k = p.carried_index(step.object, field=f"{where}.detach")
        carried = p.attached.pop(k)
        p.resting = {r for r in p.resting if r[0] != step.object}
        p.obstacles.append(detach(p.frames, carried, p.vec(), where=f"{where}.detach"))
        held = (step.object, carried.link)
    p.done.append(StepResult(at, step.kind, step.label, start, dict(p.q),
                             step.seconds if isinstance(step, WaitStep) else 0.0,
                             None, tuple(a.id for a in p.attached), object=held[0],
                             link=held[1], part_of=part_of, touch_links=touch, mass=mass,
                             attached=tuple(p.attached), obstacles=tuple(p.obstacles),
                             allowed=tuple(sorted(p.resting))))


def _cores(p: Progress, pairs: tuple[tuple[str, str], ...]
           ) -> tuple[tuple[Obstacle, ...], tuple[tuple[str, str], ...]]:
    """For the (carried object, support) ``pairs`` a motion allows to touch: each
    support's core (:func:`arduinobot.planner.planning.resting.cores_for`: the support
    shrunk by :data:`~arduinobot.planner.planning.resting.DEPTH`, checked against that
    object only), so the motion's certificate proves the object never presses deeper
    than that into its support, whatever the motion. A support without a core (a mesh, or
    too thin) keeps the bare allowance, as before."""
    if not pairs:  # most steps: nothing resting, nothing to build
        return (), ()
    held = {a.id for a in p.attached}
    obstacles = with_ground(tuple(p.obstacles), p.task.ground)
    known = {o.id for o in obstacles}
    links = p.planner.world(()).bodies.names
    cores: list[Obstacle] = []
    more: list[tuple[str, str]] = []
    for pair in pairs:
        if pair[0] not in held or pair[1] not in known:
            continue
        found = cores_for([pair], [*obstacles, *cores], p.attached, links)
        if found is None:
            _log.debug("no core for %s: the pair %s is allowed unproven", pair[1], pair)
            continue
        cores.extend(found[0])
        more.extend(found[1][1:])  # the pair itself is allowed already
    return tuple(cores), tuple(more)


def _request(task: Task, options: MotionOptions, goal: Goal, group: str | None,
             start: Mapping[str, float], obstacles: list[Obstacle],
             attached: list[AttachedObject], index: int, *,
             allowed: tuple[tuple[str, str], ...] = ()) -> MotionRequest:
    return MotionRequest(
        goal=goal, start=dict(start), group=group, obstacles=tuple(obstacles),
        attached=tuple(attached), clouds=task.clouds, ground=task.ground,
        planning_time=options.planning_time or task.planning_time,
        velocity_scaling=options.velocity_scaling or task.velocity_scaling,
        acceleration_scaling=options.acceleration_scaling or task.acceleration_scaling,
        # each motion its own seed, in the seeds' range
        seed=None if task.seed is None else (task.seed + index) % (MAX_SEED + 1),
        allowed=allowed)
