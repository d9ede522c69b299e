"""How a wire object becomes an object of the kept scene (:class:`SceneBuilder`): its frame
and id checked against the robot's links, its inline mesh stored (here, or by a
:class:`MeshStore`: the service's worker), a point cloud kept at the robot's state."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.frames import Frames
from arduinobot.scene.obstacles import AttachedObject, Obstacle, rigid_links
from arduinobot.scene.shapes import check_inline, shape_class
from arduinobot.scene.state import WORLD, SceneAttached, SceneCloud, SceneObject


class MeshStore(Protocol):
    """Who parses an inline mesh and writes its file (the service: a worker process)."""

    def store_mesh(self, data: Mapping[str, Any], *, where: str, folder: Path
                   ) -> dict[str, Any]:
        """:meth:`arduinobot.scene.shapes.Mesh.stored` of ``data`` (refusals name
        fields under ``where``)."""
        ...


class SceneBuilder:
    """Turns wire objects into :class:`SceneObject` for one robot (its link names may not
    be object ids or frames) and one folder for mesh files; with ``robot`` (its link
    poses and collision checks) it can attach and detach too; with ``meshes`` its inline
    meshes are parsed there (else here)."""

    def __init__(self, link_names: Sequence[str], mesh_dir: str | os.PathLike[str], *,
                 robot: Frames | None = None, meshes: MeshStore | None = None) -> None:
        self.link_names = frozenset(link_names)
        self.mesh_dir = Path(mesh_dir)
        self.robot = robot
        self.meshes = meshes

    def build(self, data: Mapping[str, Any], where: str) -> SceneObject:
        """One object (schema-valid, see ``scene_apply_request.json``) at field ``where``.

        An object in a link's frame moves with that link: it is checked against the scene
        and every link but those rigidly joined to its own (:func:`arduinobot.scene.obstacles.rigid_links`).

        Raises:
            InvalidRequest: an unknown frame (or a link's without a robot model), an id
                that is a link name, a bad primitive or mesh.
        """
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object", field=where)
        frame = data.get("frame", WORLD)
        if frame != WORLD and frame not in self.link_names:
            raise InvalidRequest(f"'{frame}' is neither 'world' nor a link of the robot",
                                 field=f"{where}.frame",
                                 details={"links": sorted(self.link_names)})
        if frame != WORLD and self.robot is None:
            raise InvalidRequest("this scene holds objects in the world only (no robot "
                                 "model)", field=f"{where}.frame")
        oid = data.get("id")
        if oid in self.link_names:
            raise InvalidRequest(f"id '{oid}' is also a link name", field=f"{where}.id")
        geometry = {k: v for k, v in data.items() if k not in ("frame", "touch_links")}
        if "shape" in data:  # (without one, the obstacle names the missing field)
            cls = shape_class(data["shape"], field=f"{where}.shape")
            check_inline(cls, data, where=where)
            if self.meshes is not None and cls.kind == "mesh" and "mesh" in geometry:
                geometry = self.meshes.store_mesh(geometry, where=where,
                                                  folder=self.mesh_dir)
            else:
                geometry = cls.stored(geometry, where=where, folder=self.mesh_dir)
        obstacle = Obstacle.from_mapping(geometry, where=where)
        extra = data.get("touch_links") or ()
        if frame == WORLD:
            if "touch_links" in data:
                raise InvalidRequest("only an object in a link's frame takes it (a carried "
                                     "object's are its attach's)", field=f"{where}.touch_links")
            return SceneObject(obstacle.id, dict(data), obstacle)
        for i, t in enumerate(extra):
            if t not in self.link_names:
                raise InvalidRequest(f"'{t}' is not a link of the robot",
                                     field=f"{where}.touch_links[{i}]")
        assert self.robot is not None  # refused above
        rigid = rigid_links(self.robot.description, frame)
        touch = rigid + tuple(t for t in extra if t not in rigid)
        return SceneObject(obstacle.id, dict(data), obstacle,
                           AttachedObject(obstacle, frame, touch, where=where))


    def build_cloud(self, data: Mapping[str, Any], where: str, state: Any, *,
                    objects: Iterable[SceneObject],
                    carried: Iterable[SceneAttached]) -> SceneCloud:
        """A point cloud (``shape: "points"``, see :mod:`arduinobot.scene.cloud_spec`)
        kept at the robot's ``state`` (``{joint: value}``, None: all 0), less the robot's
        cells there and those in the free ``objects`` and the ``carried`` ones (objects
        in a link's frame are carried).

        Raises:
            InvalidRequest: no robot model; the cloud's own refusals, naming the field.
        """
        if self.robot is None:
            raise InvalidRequest("this scene keeps no point cloud (no robot model to "
                                 "filter it by)", field=f"{where}.shape")
        q = self.robot.state(state, field="state")
        free = [o for o in objects if o.fixed is None]
        held = [a.attached for a in carried] + [o.fixed for o in objects
                                                 if o.fixed is not None]
        bodies, counts = self.robot.keep_cloud(dict(data), q, where=where,
                                               objects=[o.obstacle for o in free],
                                               attached=held)
        return SceneCloud(str(data["id"]), {**data, "state": dict(state or {})},
                          tuple(bodies), counts)
