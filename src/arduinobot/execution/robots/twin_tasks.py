"""A planned task run on the twin: the objects it picks up as loose bodies, and when it
grips and lets go of them (an executor ``on_tick`` that welds and frees them).

Pure bookkeeping over :class:`arduinobot.planner.tasks.TaskResult`: the service's task reply uses it
(:func:`arduinobot.service.task.task_service.twin_body`) without importing the simulator.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any, Protocol

log = logging.getLogger(__name__)


class Grips(Protocol):
    """A robot that can weld an object to its link and let it go (the twin)."""

    def grasp(self, object_id: str, hold: bool) -> None: ...


def task_objects(task: Any, result: Any) -> tuple[Any, ...]:
    """The objects a planned task (:class:`arduinobot.planner.tasks.Task` and its
    :class:`arduinobot.planner.tasks.TaskResult`) picks up, as the twin's ``loose`` objects: each
    where the task's scene has it, held by the attach step's link with its touch links
    and mass (an attach step's own, or one a pick step generated)."""
    from arduinobot.scene.obstacles import AttachedObject
    scene = {o.id: o for o in result.start_obstacles}
    out: dict[str, Any] = {}
    for s in result.steps:
        if s.kind == "attach" and s.object in scene and s.object not in out:
            out[s.object] = AttachedObject(shape=scene[s.object], link=s.link,
                                           touch_links=s.touch_links, mass=s.mass)
    return tuple(out.values())


def without(obstacles: Sequence[Any], objects: Sequence[Any]) -> list[Any]:
    """``obstacles`` less the ``objects`` the twin simulates as loose bodies."""
    ids = {a.id for a in objects}
    return [o for o in obstacles if (o["id"] if isinstance(o, dict) else o.id) not in ids]


#: a grip switch of a task: (task time [s], object id, held from then on)
Grasp = tuple[float, str, bool]


def task_grasps(result: Any) -> list[Grasp]:
    """When a planned task grips and lets go of its objects: its attach and detach
    steps' start times."""
    return [(t0, s.object, s.kind == "attach")
            for s, t0 in zip(result.steps, result.boundaries())
            if s.kind in ("attach", "detach") and s.object is not None]


def grasp_schedule(robot: Grips, grasps: Any) -> Callable[[Any], None]:
    """An executor ``on_tick`` for ``robot`` running a task joined into one trajectory
    (its time the task's): at the first tick at or past each grasp's time
    (``grasps``, or a :class:`arduinobot.planner.tasks.TaskResult`: :func:`task_grasps`) the
    object is welded to its link, or let go."""
    pending = sorted(task_grasps(grasps) if hasattr(grasps, "steps") else grasps,
                     key=lambda g: g[0])

    def on_tick(tick: Any) -> None:
        while pending and tick.phase in ("trajectory", "stop") \
                and tick.trajectory_time >= pending[0][0] - 1e-9:
            _, obj, hold = pending.pop(0)
            robot.grasp(obj, hold)
            log.info("twin: %s %s at %.3f s", "gripped" if hold else "let go", obj,
                     tick.trajectory_time)
    return on_tick
