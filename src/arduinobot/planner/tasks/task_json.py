"""A task read from its JSON form (the service's ``<prefix>/task`` request, a
``tasks.yaml`` entry; the form: :mod:`arduinobot.planner.tasks.steps`): a bad step refused
with :class:`~arduinobot.contract.errors.InvalidRequest` naming its field
(``steps[3].gripper``).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from typing import Any

from arduinobot.contract.errors import InvalidRequest, unknown_fields, unknown_names
from arduinobot.planner.planning.goals import (
    goal_from_mapping,
    line_from_mapping,
)
from arduinobot.planner.planning.pathfinding.search import check_seed
from arduinobot.planner.tasks.steps import (
    APPROACH,
    LIFT,
    MAX_MASS,
    MAX_REACH,
    MAX_WAIT,
    STEP_KINDS,
    AttachStep,
    DetachStep,
    GripperStep,
    MotionOptions,
    MoveStep,
    PickStep,
    PlaceStep,
    PlaceTarget,
    Step,
    Task,
    WaitStep,
)
from arduinobot.scene.obstacles import Obstacle


def _number(value: object, where: str, *, low: float = -math.inf,
            high: float = math.inf, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or not low <= value <= high:
        # the bound broken, as a schema's refusal gives it (details.limit)
        limit = None
        if isinstance(value, (int, float)) and not isinstance(value, bool) \
                and math.isfinite(value):
            limit = high if value > high else low
        raise InvalidRequest(f"{value!r} must be a number in [{low:g}, {high:g}]"
                             + (f" [{unit}]" if unit else ""), field=where,
                             details={"limit": limit} if limit is not None else None)
    return float(value)


_MOTION_KEYS = {"velocity_scaling", "acceleration_scaling", "planning_time"}
_KEYS: dict[str, set[str]] = {
    "move": {"group", *_MOTION_KEYS}, "line": set(_MOTION_KEYS), "gripper": set(_MOTION_KEYS),
    "attach": {"link", "mass", "touch_links", "reach"}, "detach": set(), "wait": set(),
    "pick": {"approach", "lift", "mass", "grasp", *_MOTION_KEYS},
    "place": {"at", "approach", *_MOTION_KEYS}}


def _options(data: Mapping[str, Any], where: str) -> MotionOptions:
    def opt(key: str, low: float, high: float) -> float | None:
        return None if key not in data else _number(data[key], f"{where}.{key}", low=low,
                                                    high=high)
    return MotionOptions(opt("velocity_scaling", 0.01, 1.0),
                         opt("acceleration_scaling", 0.01, 1.0),
                         opt("planning_time", 1e-3, 60.0))


def step_from_mapping(data: object, where: str) -> Step:
    """One step of a task's JSON form (see the module's docstring)."""
    if not isinstance(data, Mapping):
        raise InvalidRequest(f"must be an object with one of {', '.join(STEP_KINDS)}",
                             field=where)
    kinds = [k for k in STEP_KINDS if k in data]
    if len(kinds) != 1:
        guesses = [k for k in data if isinstance(k, str) and k not in STEP_KINDS
                   and difflib.get_close_matches(k, STEP_KINDS, n=1, cutoff=0.6)]
        raise InvalidRequest(f"give exactly one of {', '.join(STEP_KINDS)}"
                             + (f"; unknown {unknown_names(guesses, STEP_KINDS)}"
                                if guesses else ""), field=where)
    kind = kinds[0]
    extra = sorted(set(data) - {kind, "label"} - _KEYS[kind])
    if extra:
        raise InvalidRequest(unknown_fields(extra, {kind, "label", *_KEYS[kind]},
                                            of=f"a {kind} step"), field=where)
    label = data.get("label")
    if label is not None and not isinstance(label, str):
        raise InvalidRequest("must be a string", field=f"{where}.label")
    value = data[kind]
    at = f"{where}.{kind}"
    if kind == "move":
        group = data.get("group")
        if group is not None and not isinstance(group, str):
            raise InvalidRequest("must be a group name", field=f"{where}.group")
        return MoveStep(goal_from_mapping(value, at), group=group,
                        options=_options(data, where), label=label)
    if kind == "line":
        return MoveStep(line_from_mapping(value, at), options=_options(data, where),
                        label=label)
    if kind == "gripper":
        return GripperStep(_gripper_command(value, at), options=_options(data, where),
                           label=label)
    if kind in ("pick", "place"):
        return _pick_or_place(kind, value, data, where, label)
    if kind in ("attach", "detach"):
        if not isinstance(value, str) or not value:
            raise InvalidRequest("must be an obstacle id", field=at)
        if kind == "detach":
            return DetachStep(value, label=label)
        link = data.get("link")
        if link is not None and not isinstance(link, str):
            raise InvalidRequest("must be a link name", field=f"{where}.link")
        touch = data.get("touch_links", ())
        if not isinstance(touch, Sequence) or isinstance(touch, str) \
                or not all(isinstance(t, str) for t in touch):
            raise InvalidRequest("must be a list of link names", field=f"{where}.touch_links")
        return AttachStep(value, link=link,
                          mass=_number(data.get("mass", 0.0), f"{where}.mass", low=0.0,
                                       high=MAX_MASS, unit="kg"),
                          touch_links=tuple(touch), label=label,
                          reach=None if "reach" not in data else _number(
                              data["reach"], f"{where}.reach", low=0.0, high=MAX_REACH,
                              unit="m"))
    return WaitStep(_number(value, at, low=0.0, high=MAX_WAIT, unit="s"), label=label)


def _object_id(value: object, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise InvalidRequest("must be an obstacle id", field=where)
    return value


def _pick_or_place(kind: str, value: object, data: Mapping[str, Any], where: str,
                   label: str | None) -> Step:
    at = f"{where}.{kind}"
    obj = _object_id(value, at)
    approach = _number(data.get("approach", APPROACH), f"{where}.approach", low=0.0,
                       high=1.0, unit="m")
    options = _options(data, where)
    if kind == "place":
        if "at" not in data:
            raise InvalidRequest("a place needs 'at': {position: [x, y, z]}, {on: OBSTACLE} "
                                 "or a place's name", field=f"{where}.at")
        return PlaceStep(obj, place_target(data["at"], f"{where}.at"), approach=approach,
                         options=options, label=label)
    grasp = data.get("grasp", {})
    if not isinstance(grasp, Mapping):
        raise InvalidRequest("must be an object {approach, height}", field=f"{where}.grasp")
    extra = sorted(set(grasp) - {"approach", "height"})
    if extra:
        raise InvalidRequest(unknown_fields(extra, {"approach", "height"}, of="grasp hints"),
                             field=f"{where}.grasp")
    hints: dict[str, object] = {}
    if "approach" in grasp:
        if grasp["approach"] not in ("fingers", "above"):
            raise InvalidRequest(f"{grasp['approach']!r} must be fingers (along the claw) "
                                 "or above (straight down)", field=f"{where}.grasp.approach")
        hints["approach"] = grasp["approach"]
    if "height" in grasp:
        hints["height"] = _number(grasp["height"], f"{where}.grasp.height", low=-1.0,
                                  high=1.0, unit="m")
    return PickStep(obj, approach=approach,
                    lift=_number(data.get("lift", LIFT), f"{where}.lift", low=0.0, high=1.0,
                                 unit="m"),
                    mass=_number(data.get("mass", 0.0), f"{where}.mass", low=0.0,
                                 high=MAX_MASS, unit="kg"),
                    grasp=hints, options=options, label=label)


def place_target(value: object, where: str) -> PlaceTarget:
    """A place's ``at`` (or a named place): ``{position: [x, y, z]}``, ``{on: ID}`` or a
    name."""
    if isinstance(value, str) and value:
        return PlaceTarget(name=value)
    if not isinstance(value, Mapping) or len(value) != 1 \
            or next(iter(value)) not in ("position", "on"):
        raise InvalidRequest(f"{value!r} must be {{position: [x, y, z]}}, {{on: OBSTACLE}} "
                             "or a place's name", field=where)
    if "on" in value:
        return PlaceTarget(on=_object_id(value["on"], f"{where}.on"))
    p = value["position"]
    if not isinstance(p, Sequence) or isinstance(p, str) or len(p) != 3:
        raise InvalidRequest("must be [x, y, z] [m]", field=f"{where}.position")
    x, y, z = (_number(v, f"{where}.position[{i}]", unit="m") for i, v in enumerate(p))
    return PlaceTarget(position=(x, y, z))


def places_from_mapping(data: object, where: str) -> dict[str, PlaceTarget]:
    """A tasks.yaml's (or a task's) ``places``: ``{NAME: {position: [...]} | {on: ID} |
    ID}``."""
    if not isinstance(data, Mapping):
        raise InvalidRequest("must map place names to {position: [x, y, z]}, {on: "
                             "OBSTACLE} or an obstacle id", field=where)
    out = {}
    for name, v in data.items():
        t = place_target(v, f"{where}.{name}")
        out[str(name)] = PlaceTarget(on=t.name) if t.name is not None else t
    return out


def _gripper_command(value: object, where: str) -> str | float | tuple[float, ...]:
    if isinstance(value, str) and value:
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return _number(value, where)
    if isinstance(value, Sequence) and not isinstance(value, str) and 1 <= len(value) <= 8:
        return tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(value))
    raise InvalidRequest(f"{value!r} must be open, close, a named state, a value [rad] or "
                         "values (the leader, then its mimics)", field=where)


def task_from_mapping(data: object, *, where: str = "", name: str | None = None,
                      files: bool = True) -> Task:
    """A :class:`Task` from its JSON form; ``where`` prefixes every field named in an
    error (``tasks.pick.steps[2]``); ``files``: whether its obstacles may name files of
    this machine (False for a task from the wire: :meth:`.Obstacle.from_mapping`)."""
    pre = f"{where}." if where else ""
    if isinstance(data, Sequence) and not isinstance(data, str):
        data = {"steps": data}  # a tasks.yaml entry may be its steps alone
    if not isinstance(data, Mapping):
        raise InvalidRequest("must be an object with steps", field=where or "task")
    known = {"steps", "start", "obstacles", "velocity_scaling", "acceleration_scaling",
             "planning_time", "seed", "name", "description", "ground", "places"}
    extra = sorted(set(data) - known)
    if extra:
        raise InvalidRequest(unknown_fields(extra, known, of="a task"), field=where or "task")
    steps = data.get("steps")
    if not isinstance(steps, Sequence) or isinstance(steps, str) or not steps:
        raise InvalidRequest("must be a non-empty list of steps", field=f"{pre}steps")
    start = data.get("start")
    if start is not None and not isinstance(start, Mapping):
        raise InvalidRequest("must map joint names to values [rad]", field=f"{pre}start")
    obstacles = data.get("obstacles", ())
    if not isinstance(obstacles, Sequence) or isinstance(obstacles, str):
        raise InvalidRequest("must be a list of obstacles", field=f"{pre}obstacles")
    seed = data.get("seed")
    check_seed(seed, f"{pre}seed")
    ground = data.get("ground", True)
    if not isinstance(ground, bool):
        raise InvalidRequest(f"{ground!r} must be true or false (false: the plane the base "
                             "stands on is no obstacle)", field=f"{pre}ground")
    vs, acc = data.get("velocity_scaling"), data.get("acceleration_scaling")
    return Task(
        steps=tuple(step_from_mapping(s, f"{pre}steps[{i}]") for i, s in enumerate(steps)),
        start=None if start is None else {str(k): _number(v, f"{pre}start.{k}")
                                          for k, v in start.items()},
        obstacles=tuple(o if isinstance(o, Obstacle) else
                        Obstacle.from_mapping(o, where=f"{pre}obstacles[{i}]", files=files)
                        for i, o in enumerate(obstacles)),
        velocity_scaling=None if vs is None else _number(vs, f"{pre}velocity_scaling",
                                                         low=0.01, high=1.0),
        acceleration_scaling=None if acc is None else _number(
            acc, f"{pre}acceleration_scaling", low=0.01, high=1.0),
        planning_time=_number(data.get("planning_time", 1.0), f"{pre}planning_time",
                              low=1e-3, high=60.0),
        seed=seed, name=name if name is not None else data.get("name"), ground=ground,
        places=places_from_mapping(data.get("places", {}), f"{pre}places"))
