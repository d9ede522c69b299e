"""What the execute service's twin holds of the world: the kept scene's objects and
carried objects, a plan's own obstacles, or a task's objects, given to the twin
(``SimArduinobot.set_scene``) only when they changed: before an execution, and at a
blend's switch tick (the arm moving on). A real arm has no scene to give."""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from arduinobot.contract import wire
from arduinobot.execution.robots.base import Robot

if TYPE_CHECKING:
    from arduinobot.scene.state import SceneSnapshot

_log = logging.getLogger(__name__)

#: (the kept scene's revision, the plan's or task's own obstacles encoded, a task's,
#: the ground)
Held = tuple[int, bytes, bool, bool]


class TwinScene:
    """The scene one twin holds (none at first: the twin opens bare)."""

    def __init__(self) -> None:
        self.held: Held | None = None

    def give(self, robot: Robot, snap: SceneSnapshot | None,
             own: Sequence[Mapping[str, Any]], twin: Mapping[str, Any] | None = None,
             *, ground: bool = True, keep_loose: bool = False) -> None:
        """Give a twin (a robot with ``set_scene``) the kept scene's objects (``snap``),
        the plan's ``own`` obstacles and the carried objects, when they changed since the
        last time; a task's ``twin`` (its obstacles, the kept scene's among them, and the
        objects it picks up as loose bodies, put back where it has them) instead of the
        plan's. ``ground``: a floor at z = 0 as the plan (or the task's ``twin``) had
        its ground (:mod:`arduinobot.scene.ground`). ``keep_loose``: the task's objects
        the twin has already stay as simulated (where they lie, which are gripped): a
        task planned again from where the arm stopped."""
        set_scene = getattr(robot, "set_scene", None)
        if set_scene is None:
            return
        if twin is not None:
            own = twin.get("obstacles") or ()
            ground = bool(twin.get("ground", True))
        key = (snap.revision if snap is not None else 0, wire.encode(list(own)),
               twin is not None, ground)
        # a task's objects start where its scene has them: rebuilt for every task
        if key == self.held and twin is None:
            return
        # a kept cloud's cells go in as static boxes (execution/robots/twin_clouds.py)
        obstacles: tuple[Any, ...] = (*snap.obstacles, *snap.clouds) if snap is not None \
            else ()
        attached = snap.attached if snap is not None else ()
        if twin is None:
            set_scene([*obstacles, *own], attached, ground=ground)
        else:
            from arduinobot.scene.obstacles import AttachedObject
            loose = [AttachedObject.from_mapping(o, where=f"twin.objects[{i}]")
                     for i, o in enumerate(twin.get("objects") or ())]
            mine = {o["id"] for o in own} | {a.id for a in loose}
            kept = [o for o in obstacles if o.id not in mine]
            set_scene([*kept, *own], attached, loose=loose, ground=ground,
                      keep_loose=keep_loose)
        self.held = key

    def at_switch(self, robot: Robot, snap: SceneSnapshot | None,
                  own: Sequence[Mapping[str, Any]], *, ground: bool = True
                  ) -> Callable[[], None] | None:
        """What a blend does to the twin at its switch tick (``Executor.switch``'s
        ``on_switch``, on the executing thread): put in the world its plan was made in
        (the kept scene ``snap`` and the blend plan's ``own`` obstacles), the arm keeping
        its motion. None when the twin holds that world already, when ``robot`` is no
        twin, or when the twin plays a task's objects: a blend keeps them as the
        simulation has them (where they lie, which are gripped)."""
        set_scene = getattr(robot, "set_scene", None)
        if set_scene is None:
            return None
        key = (snap.revision if snap is not None else 0, wire.encode(list(own)), False,
               ground)
        if key == self.held:
            return None
        if self.held is not None and self.held[2]:
            _log.info("twin: the blend keeps the running task's objects; the scene at "
                      "revision %d is not put in", key[0])
            return None
        obstacles: tuple[Any, ...] = (*snap.obstacles, *snap.clouds) if snap is not None \
            else ()
        attached = snap.attached if snap is not None else ()

        def switch() -> None:
            set_scene([*obstacles, *own], attached, moving=True, ground=ground)
            self.held = key
            _log.info("twin: the blend's world at its switch: scene revision %d, %d "
                      "objects, %d carried, %d of the plan's own", key[0], len(obstacles),
                      len(attached), len(own))
        return switch
