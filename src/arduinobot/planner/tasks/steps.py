"""What a task is: a start state, obstacles and an ordered list of steps.

A task's JSON form (the service's ``<prefix>/task`` request, a ``tasks.yaml`` entry) is
``{"start": {joint: rad}, "obstacles": [...], "steps": [...]}`` (and ``"ground": false``
for an arm whose base plane is no obstacle, :mod:`arduinobot.scene.ground`) with one key
naming each step's kind::

    {"move": GOAL}                 any plan goal (joints, named, position, line), "group"
    {"line": {"offset": [dx, dy, dz], "frame": "world" | "tcp"}}   a straight tcp move
    {"gripper": "open" | "close" | NAME | value | [value, mimic value]}
    {"attach": OBJECT_ID, "link": LINK, "mass": kg, "touch_links": [...], "reach": m}
    {"detach": OBJECT_ID}
    {"wait": seconds}
    {"pick": OBJECT_ID, "approach": m, "lift": m, "mass": kg, "grasp": {"approach":
     "fingers" | "above", "height": m}}          grasps generated (pick.py)
    {"place": OBJECT_ID, "at": {"position": [x, y, z]} | {"on": OBSTACLE_ID} | NAME,
     "approach": m}                               a place named in ``places`` or an obstacle

and optional ``label``, ``velocity_scaling``, ``acceleration_scaling`` and
``planning_time`` on a motion step. Read by :mod:`arduinobot.planner.tasks.task_json`, which
refuses a bad step naming its field (``steps[3].gripper``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from arduinobot.contract.errors import InvalidRequest
from arduinobot.planner.planning.goals import Goal, LineGoal
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle

StepKind = Literal["move", "line", "gripper", "attach", "detach", "wait", "pick", "place"]
STEP_KINDS: tuple[StepKind, ...] = ("move", "line", "gripper", "attach", "detach", "wait",
                                    "pick", "place")
#: [m] a pick's way in and a place's way down by default, and a pick's lift
APPROACH = 0.05
LIFT = 0.05
#: the longest wait step [s]: a task is a motion, not a timer
MAX_WAIT = 60.0
#: [m] the largest ``reach`` an attach step may give (a grip a metre from the object is
#: no grip)
MAX_REACH = 1.0
#: the heaviest object an attach step may give [kg]: plan_request.json's attached mass
#: (past it the inverse dynamics overflows: a NaN effort at 1e308 kg)
MAX_MASS = 1000.0


@dataclass(frozen=True)
class MotionOptions:
    """A motion step's own scalings ([0.01, 1], None: the task's) and planning time [s]."""

    velocity_scaling: float | None = None
    acceleration_scaling: float | None = None
    planning_time: float | None = None


@dataclass(frozen=True)
class MoveStep:
    """Move the ``group`` (None: the goal's, else the default group) to ``goal``; a
    :class:`~arduinobot.planner.planning.goals.LineGoal` makes it a straight tcp move (``line``)."""

    goal: Goal
    group: str | None = None
    options: MotionOptions = MotionOptions()
    label: str | None = None

    @property
    def kind(self) -> StepKind:
        return "line" if isinstance(self.goal, LineGoal) else "move"


@dataclass(frozen=True)
class GripperStep:
    """Move the gripper group: ``open``/``close`` (its SRDF state ``open``/
    ``gripper_open``, ``close``/``closed``/``gripper_closed``), another named state of
    it, or its leading joint's value [rad] (a pair: the leader and its mimic, which must
    agree)."""

    command: str | float | tuple[float, ...]
    options: MotionOptions = MotionOptions()
    label: str | None = None
    kind: StepKind = field(default="gripper", init=False)


@dataclass(frozen=True)
class AttachStep:
    """The obstacle ``object`` becomes part of the robot, held by ``link`` (None: the
    end effector's parent link) where it is now, for every step after this one; refused
    farther than ``reach`` [m] from what would hold it (None: 3 cm,
    :data:`arduinobot.scene.frames.MAX_GRASP_DISTANCE`)."""

    object: str
    link: str | None = None
    mass: float = 0.0
    touch_links: tuple[str, ...] = ()
    label: str | None = None
    reach: float | None = None
    kind: StepKind = field(default="attach", init=False)


@dataclass(frozen=True)
class DetachStep:
    """The carried ``object`` is put back into the scene where it is now."""

    object: str
    label: str | None = None
    kind: StepKind = field(default="detach", init=False)


@dataclass(frozen=True)
class WaitStep:
    """Hold still for ``seconds`` [s]."""

    seconds: float
    label: str | None = None
    kind: StepKind = field(default="wait", init=False)


@dataclass(frozen=True)
class PickStep:
    """Pick ``object`` up: grasps generated from its shape and the claw
    (:mod:`arduinobot.planner.tasks.pick`), the first that plans whole taken; the claw
    comes in ``approach`` [m] and lifts it ``lift`` [m]; ``mass`` [kg] carried;
    ``grasp`` hints (``approach``: fingers or above, ``height`` [m] over its centre)."""

    object: str
    approach: float = APPROACH
    lift: float = LIFT
    mass: float = 0.0
    grasp: Mapping[str, Any] = field(default_factory=dict)
    options: MotionOptions = MotionOptions()
    label: str | None = None
    kind: StepKind = field(default="pick", init=False)


@dataclass(frozen=True)
class PlaceTarget:
    """Where a place puts its object: its centre at ``position`` [m], on top of the
    obstacle ``on``, or the task's place ``name`` (or, lacking one, the obstacle so
    named)."""

    position: tuple[float, float, float] | None = None
    on: str | None = None
    name: str | None = None


@dataclass(frozen=True)
class PlaceStep:
    """Put the carried ``object`` down ``at`` (:mod:`arduinobot.planner.tasks.place`):
    lowered ``approach`` [m] straight down, let go, the claw back up as far."""

    object: str
    at: PlaceTarget
    approach: float = APPROACH
    options: MotionOptions = MotionOptions()
    label: str | None = None
    kind: StepKind = field(default="place", init=False)


Step = MoveStep | GripperStep | AttachStep | DetachStep | WaitStep | PickStep | PlaceStep


@dataclass(frozen=True)
class Task:
    """A start state [rad] (None: every actuated joint at 0), the scene's obstacles, the
    steps, and the options every motion step shares (a step's own override them)."""

    steps: tuple[Step, ...]
    start: Mapping[str, float] | None = None
    obstacles: tuple[Obstacle, ...] = ()
    #: the kept scene's point clouds (cells), avoided by every motion step
    clouds: tuple[CloudObstacle, ...] = ()
    velocity_scaling: float | None = None
    acceleration_scaling: float | None = None
    planning_time: float = 1.0
    seed: int | None = None
    name: str | None = None
    #: the plane the base stands on is an obstacle of every motion step
    #: (:mod:`arduinobot.scene.ground`) unless False
    ground: bool = True
    #: named places a place step's ``at`` may name (a tasks.yaml's ``places``)
    places: Mapping[str, PlaceTarget] = field(default_factory=dict)
    #: what the robot carries at the start (a task's rest replanned mid-way, after an
    #: attach), and the (object, obstacle) pairs touching then, allowed until cleared
    carrying: tuple[AttachedObject, ...] = ()
    resting: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        if not self.steps:
            raise InvalidRequest("a task needs at least one step", field="steps")
