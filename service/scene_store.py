"""The planning scene that lasts: its objects at a revision, how an apply changes it
(all or nothing), and its file on disk.

A :class:`SceneState` is immutable: :func:`apply` builds the next one or raises, so a
refused apply leaves the scene as it was by construction. Each object keeps its wire form
(what ``<prefix>/scene`` answers, meshes as sent) and its
:class:`~planner.scene.Obstacle` (a mesh as its content-addressed file, see
:mod:`service.scene_mesh`), which is what plans and checks use. The sharing between
instances is :mod:`service.scene_sync`'s.
"""

from __future__ import annotations

import json
import logging
import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from planner.errors import InvalidRequest, SceneConflict
from planner.scene import Obstacle

from .scene_mesh import decode_mesh, scale_of

_log = logging.getLogger(__name__)

#: Most objects a scene holds (as many as a plan request's own obstacles).
MAX_SCENE_OBJECTS = 256
#: The frame every object is placed in today: objects in a link's frame need the
#: collision world to move them with the link, which it cannot yet.
WORLD = "world"
#: An apply's fields that are part of the format but not yet served (issue 28, item 2):
#: refused, never stored, so no plan can ignore an attachment.
NOT_YET = ("attach", "detach")


@dataclass(frozen=True)
class SceneObject:
    """One object of the scene: ``data`` its wire form, ``obstacle`` its geometry."""

    id: str
    data: Mapping[str, Any]
    obstacle: Obstacle


@dataclass(frozen=True)
class SceneSnapshot:
    """What a plan or check needs of the scene: its revision and obstacles (small: a
    mesh is a file path), sent with each job to a worker."""

    revision: int
    obstacles: tuple[Obstacle, ...] = ()


@dataclass(frozen=True)
class SceneState:
    """The scene at one revision (0: empty, never changed)."""

    revision: int = 0
    objects: tuple[SceneObject, ...] = ()
    snapshot: SceneSnapshot = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "snapshot", SceneSnapshot(
            self.revision, tuple(o.obstacle for o in self.objects)))

    def to_json(self) -> dict[str, Any]:
        """The ``<prefix>/scene`` reply (and the scene file)."""
        return {"revision": self.revision, "objects": [dict(o.data) for o in self.objects],
                "attached": []}

    def ids(self) -> tuple[str, ...]:
        return tuple(o.id for o in self.objects)


class SceneBuilder:
    """Turns wire objects into :class:`SceneObject` for one robot (its link names may not
    be object ids or frames) and one folder for mesh files."""

    def __init__(self, link_names: Sequence[str], mesh_dir: str | os.PathLike[str]) -> None:
        self.link_names = frozenset(link_names)
        self.mesh_dir = Path(mesh_dir)

    def build(self, data: Mapping[str, Any], where: str) -> SceneObject:
        """One object (schema-valid, see ``scene_apply_request.json``) at field ``where``.

        Raises:
            InvalidRequest: a link's frame (not yet supported) or an unknown frame, an id
                that is a link name, a bad primitive or mesh.
        """
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object", field=where)
        frame = data.get("frame", WORLD)
        if frame != WORLD:
            if frame in self.link_names:
                raise InvalidRequest(
                    f"objects in a link's frame ('{frame}') are not yet supported: the "
                    "collision world holds world-fixed objects only; give the pose in "
                    "'world'", field=f"{where}.frame", details={"unsupported": "frame"})
            raise InvalidRequest(f"'{frame}' is neither 'world' nor a link of the robot",
                                 field=f"{where}.frame")
        oid = data.get("id")
        if oid in self.link_names:
            raise InvalidRequest(f"id '{oid}' is also a link name", field=f"{where}.id")
        geometry = {k: v for k, v in data.items() if k not in ("frame", "mesh", "scale")}
        if data.get("shape") == "mesh":
            if "mesh" not in data:
                raise InvalidRequest("a mesh object needs mesh {format, data}",
                                     field=f"{where}.mesh")
            mesh = decode_mesh(data["mesh"], scale=scale_of(data.get("scale"), f"{where}.scale"),
                               field=f"{where}.mesh")
            geometry["mesh_path"] = str(mesh.write(self.mesh_dir))
        elif "mesh" in data or "scale" in data:
            bad = "mesh" if "mesh" in data else "scale"
            raise InvalidRequest("only a mesh object takes it", field=f"{where}.{bad}")
        obstacle = Obstacle.from_mapping(geometry, where=where)
        return SceneObject(obstacle.id, dict(data), obstacle)


def apply(state: SceneState, change: Mapping[str, Any], builder: SceneBuilder, *,
          max_objects: int = MAX_SCENE_OBJECTS) -> SceneState:
    """The scene after ``change`` (a schema-valid apply request), all or nothing: the
    whole scene is cleared (``clear``), then ``remove``'s ids go, then ``add``'s objects
    come, and the revision goes up by one.

    Raises:
        SceneConflict: ``if_revision`` is not ``state.revision``.
        InvalidRequest: ``attach``/``detach`` (not yet supported), removing an id the scene
            does not hold (or one twice), a duplicate id, an object the builder refuses,
            more than ``max_objects`` objects; each naming its field.
    """
    for key in NOT_YET:
        if change.get(key):
            raise InvalidRequest(f"carried objects are not yet supported ({key} comes with "
                                 "the body table that checks them): nothing was applied",
                                 field=key, details={"unsupported": key})
    if "if_revision" in change and change["if_revision"] != state.revision:
        raise SceneConflict(f"the scene is at revision {state.revision}, not "
                            f"{change['if_revision']}: read it and apply again",
                            field="if_revision", current_revision=state.revision)
    objects = {} if change.get("clear") else {o.id: o for o in state.objects}
    for i, oid in enumerate(change.get("remove") or ()):
        if oid not in objects:
            raise InvalidRequest(f"no object '{oid}' in the scene"
                                 + (" (cleared first)" if change.get("clear") else ""),
                                 field=f"remove[{i}]")
        del objects[oid]
    for i, item in enumerate(change.get("add") or ()):
        where = f"add[{i}]"
        oid = item.get("id") if isinstance(item, Mapping) else None
        if oid in objects:
            raise InvalidRequest(f"duplicate id '{oid}': the scene already holds it (remove "
                                 "it in the same apply to replace it)", field=f"{where}.id")
        obj = builder.build(item, where)
        objects[obj.id] = obj
    if len(objects) > max_objects:
        raise InvalidRequest(f"the scene would hold {len(objects)} objects, more than its "
                             f"cap of {max_objects}", field="add",
                             details={"limit": max_objects, "cap": "MAX_SCENE_OBJECTS"})
    return SceneState(state.revision + 1, tuple(objects.values()))


def restore(data: Mapping[str, Any], builder: SceneBuilder) -> SceneState:
    """A scene from its JSON form (:meth:`SceneState.to_json`: a file, or another
    instance's ``<prefix>/scene`` reply), every object validated again."""
    revision = data.get("revision")
    if isinstance(revision, bool) or not isinstance(revision, int) or revision < 0:
        raise InvalidRequest(f"{revision!r} is not a revision (an integer >= 0)",
                             field="revision")
    if data.get("attached"):
        raise InvalidRequest("carried objects are not yet supported", field="attached",
                             details={"unsupported": "attached"})
    objects = data.get("objects") or []
    if not isinstance(objects, list):
        raise InvalidRequest("must be a list of objects", field="objects")
    state = apply(SceneState(), {"add": objects}, builder)
    return SceneState(revision, state.objects)


class SceneFile:
    """The scene kept on disk: JSON written to a temporary file, synced, then renamed
    over the old one, so a crash at any moment leaves the old scene or the new one."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)

    def load(self) -> dict[str, Any] | None:
        """The scene file's JSON, or None if there is none yet.

        Raises:
            InvalidRequest: the file is not a scene (naming the file).
        """
        try:
            text = self.path.read_text("utf-8")
        except FileNotFoundError:
            return None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise InvalidRequest(f"scene file {self.path} is not JSON: {e}") from None
        if not isinstance(data, dict):
            raise InvalidRequest(f"scene file {self.path} is not a scene object")
        return data

    def save(self, state: SceneState) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=f".{self.path.name}-",
                                   suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(state.to_json(), f, separators=(",", ":"))
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        # the rename itself must reach the disk before the apply is acknowledged
        dir_fd = os.open(self.path.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)


def default_scene_file(prefix: str) -> Path:
    """Where ``arduinobot serve`` keeps the scene of ``prefix`` by default:
    ``$ARDUINOBOT_STATE``, else ``$XDG_STATE_HOME/arduinobot``, else
    ``~/.local/state/arduinobot``; one file per prefix."""
    base = os.environ.get("ARDUINOBOT_STATE")
    if not base:
        xdg = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
        base = str(Path(xdg) / "arduinobot")
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in prefix)
    return Path(base) / f"scene-{safe}.json"


def mesh_dir_for(scene_file: str | os.PathLike[str]) -> Path:
    """The folder of a scene file's canonical mesh files (beside it)."""
    return Path(scene_file).parent / "meshes"


def with_scene(snapshot: SceneSnapshot | None, data: Mapping[str, Any],
               own: tuple[Obstacle, ...]) -> tuple[tuple[Obstacle, ...], int]:
    """A plan's or check's obstacles: the kept scene's, then the request's own; and the
    scene's revision (0 without a scene: nothing kept).

    Raises:
        SceneConflict: the request pins ``scene_revision`` and the scene is elsewhere.
        InvalidRequest: a request obstacle has the id of a scene object.
    """
    snap = snapshot if snapshot is not None else SceneSnapshot(0)
    pinned = data.get("scene_revision")
    if pinned is not None and pinned != snap.revision:
        raise SceneConflict(f"the scene is at revision {snap.revision}, not {pinned}",
                            field="scene_revision", current_revision=snap.revision)
    ids = {o.id for o in snap.obstacles}
    for i, o in enumerate(own):
        if o.id in ids:
            raise InvalidRequest(f"id '{o.id}' is also an object of the kept scene (revision "
                                 f"{snap.revision})", field=f"obstacles[{i}].id")
    return snap.obstacles + own, snap.revision
