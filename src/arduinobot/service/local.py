"""The service's request -> reply path, run in this process (``arduinobot ... --local``).

A request goes through the same steps as in a worker: encoded and decoded by
:mod:`arduinobot.contract.wire` (schema, caps, finiteness), checked against the robot and answered by
:class:`arduinobot.service.plan.handlers.Handlers`; the description from :mod:`arduinobot.service.plan.bodies`, as the
``<p>/description`` reply. Imports neither Zenoh nor the server nor the worker pool.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal, get_args

from arduinobot.contract import wire
from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.planner.cache import ArtifactCache
from arduinobot.planner.frames import RobotFrames
from arduinobot.scene.builder import SceneBuilder
from arduinobot.scene.change import restore
from arduinobot.scene.state import SceneSnapshot
from arduinobot.service.plan.bodies import description_body
from arduinobot.service.plan.handlers import Handlers
from arduinobot.service.process.disk_cache import DiskCache
from arduinobot.service.scene.file import SceneFile

#: the ``request_id`` of every local reply (a worker puts its job id there)
LOCAL_REQUEST_ID = "local"


class LocalService:
    """One robot's request handlers in this process, answering as the service would."""

    def __init__(self, description: Description, *, scene_file: str | None = None,
                 cache: ArtifactCache | None | Literal["default"] = "default") -> None:
        """``cache``: where built geometry (trees, hulls, part hulls, the no-SRDF pair
        proof) is read and kept; by default the user's cache folder, the one ``serve``
        reads (:class:`~arduinobot.service.process.disk_cache.DiskCache`), so in-process
        work does not rebuild what a first run built; None keeps nothing."""
        self._description = description
        self._handlers = Handlers(description,
                                  cache=DiskCache() if cache == "default" else cache)
        #: a saved scene (``arduinobot scene save``) that plans and checks use, as the
        #: service uses its kept one
        self.scene = None if scene_file is None else load_scene(description, scene_file)

    def request(self, kind: wire.Kind, req: Mapping[str, Any]) -> dict[str, Any]:
        """The reply body to ``req`` (a JSON object) of ``kind`` (``plan``, ``fk``, ``ik``,
        ``check``).

        Raises:
            arduinobot.contract.errors.PlanningError: the coded error the service would answer with
                (InvalidRequest naming ``kind`` for a kind the service has no key for).
        """
        if kind not in get_args(wire.Kind):
            raise InvalidRequest(f"{kind!r} is not a request kind "
                                 f"({', '.join(get_args(wire.Kind))})", field="kind")
        data = wire.decode(kind, wire.encode(req))
        return {**self._handlers.handle(kind, data, scene=self.scene),
                "request_id": LOCAL_REQUEST_ID}

    def description(self) -> dict[str, Any]:
        """The ``<p>/description`` reply the service would give."""
        return description_body(self._description)


def load_scene(description: Description, path: str) -> SceneSnapshot:
    """The scene in ``path`` (as ``<prefix>/scene`` answers and ``arduinobot scene save``
    writes), every object validated as an apply would; meshes go to the user's cache
    folder, by content.

    Raises:
        InvalidRequest: no such file, not a scene, or an object the service would refuse
            (the message names the file).
    """
    try:
        data = SceneFile(path).load()
    except InvalidRequest as e:
        raise InvalidRequest(f"--scene {e.message}") from None
    if data is None:
        raise InvalidRequest(f"no scene file {path}", field="scene")
    builder = SceneBuilder(tuple(description.robot.links), DiskCache().root / "meshes",
                           robot=RobotFrames(description))  # a saved scene may carry objects
    try:
        return restore(data, builder).snapshot
    except InvalidRequest as e:
        raise InvalidRequest(f"scene file {path}: {e.message}", details=e.details) from None
