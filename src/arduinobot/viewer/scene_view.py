"""The kept scene as the viewer draws it: a ``<prefix>/scene`` reply, or a scene file
(``arduinobot scene save``), read into triangles and poses (free objects in the world,
carried objects on their link) and into what the page's collision check takes.

The objects are read by the service's own reader (:func:`arduinobot.scene.change.restore`),
so the viewer draws a mesh from the same bytes, scale and checks the planner uses, and
refuses what the service would. Pure numpy/trimesh: tested without a browser.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import orjson

from arduinobot.description import Description
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle
from arduinobot.viewer.geometry import height_colors, obstacle_mesh

#: ``revision`` of a scene that is no kept scene (nothing read from a service or a file)
NO_REVISION = -1


@dataclass(frozen=True, eq=False)
class SceneItem:
    """One object drawn: its triangles in its own frame and where that frame is.

    Attributes:
        id: the object's id.
        link: None for an object in the world; the link that carries it (or that it
            is fixed to: ``fixed``) otherwise.
        offset: its pose in the world, or in ``link``'s frame, shape (4, 4).
        vertices: shape (n, 3) [m], float32, in the object's frame.
        faces: shape (m, 3), uint32.
        key: a digest of its wire form and link: equal keys draw the same thing.
        fixed: an object of the scene in its link's frame (not carried: attached).
    """

    id: str
    link: str | None
    offset: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    key: str
    fixed: bool = False

    @property
    def carried(self) -> bool:
        return self.link is not None

    def pose(self, link_pose: np.ndarray | None = None) -> np.ndarray:
        """Its pose in the world, shape (4, 4): ``offset`` for a free object, else
        ``link_pose`` (the link's, shape (4, 4)) times ``offset``."""
        if self.link is None:
            return self.offset
        if link_pose is None:
            raise ValueError(f"'{self.id}' is carried by '{self.link}': give its pose")
        return link_pose @ self.offset


@dataclass(frozen=True, eq=False)
class CloudItem:
    """A kept cloud drawn: its kept cells' centres coloured by height.

    Attributes:
        id: the cloud body's id (``<id>.unknown`` for the shadow of unseen space).
        points: the cells' centres in the world, shape (n, 3) [m], float32.
        colors: shape (n, 3) uint8, by height (:func:`.geometry.height_colors`).
        size: the cell edge [m] (each point drawn that wide).
        key: a digest of its cells: equal keys draw the same thing.
    """

    id: str
    points: np.ndarray
    colors: np.ndarray
    size: float
    key: str

    @classmethod
    def of(cls, body: CloudObstacle) -> CloudItem:
        centers = body.cells.centers
        return cls(body.id, centers.astype(np.float32), height_colors(centers[:, 2]),
                   body.cells.resolution, hashlib.sha256(repr(body.key()).encode()).hexdigest())


@dataclass(frozen=True)
class ViewerScene:
    """A kept scene ready to draw and to check against.

    Attributes:
        revision: the scene's revision (:data:`NO_REVISION`: none was read).
        items: what is drawn, free objects first.
        obstacles: the free objects, for the collision check.
        attached: the carried objects and those fixed to a link, for the collision check.
        source: where it came from (``<prefix>/scene``, a file name), for the page.
        clouds: the point clouds' kept cells, drawn as points coloured by height.
        cloud_bodies: the same cells, for the collision check.
    """

    revision: int = NO_REVISION
    items: tuple[SceneItem, ...] = ()
    obstacles: tuple[Obstacle, ...] = ()
    attached: tuple[AttachedObject, ...] = ()
    source: str = ""
    clouds: tuple[CloudItem, ...] = ()
    cloud_bodies: tuple[CloudObstacle, ...] = ()

    @classmethod
    def from_json(cls, data: Mapping[str, Any], description: Description, *,
                  source: str = "", mesh_dir: str | Path | None = None) -> ViewerScene:
        """From ``{"revision", "objects", "attached"}`` (``<prefix>/scene``'s reply or a
        scene file), every object checked as the service checks it (against
        ``description``'s links); meshes are written to ``mesh_dir`` (default: the
        user's cache folder, by content) for the collision check.

        Raises:
            arduinobot.contract.errors.InvalidRequest: naming the object's field (``objects[2].size``,
                ``attached[0]``: a link this model does not have).
        """
        from arduinobot.planner.frames import RobotFrames
        from arduinobot.scene.builder import SceneBuilder
        from arduinobot.scene.change import restore
        from arduinobot.service.process.disk_cache import DiskCache

        folder = Path(mesh_dir) if mesh_dir is not None else DiskCache().root / "meshes"
        builder = SceneBuilder(tuple(description.robot.links), folder,
                               robot=RobotFrames(description))
        state = restore(data, builder)
        items = [_item(o.obstacle, o.link, o.data, fixed=o.link is not None)
                 for o in state.objects]
        items += [_item(a.attached.shape, a.attached.link, a.data) for a in state.attached]
        # the snapshot's carried objects hold those fixed to a link too (massless)
        bodies = state.snapshot.clouds
        return cls(state.revision, tuple(items), state.snapshot.obstacles,
                   state.snapshot.attached, source, tuple(CloudItem.of(b) for b in bodies),
                   bodies)

    def changes(self, before: ViewerScene) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """What drawing this scene over ``before`` changes: (ids to draw anew: added or
        changed, ids to take away: removed or changed)."""
        old = {i.id: i.key for i in before.items} | {c.id: c.key for c in before.clouds}
        new = {i.id: i.key for i in self.items} | {c.id: c.key for c in self.clouds}
        fresh = tuple(i for i, k in new.items() if old.get(i) != k)
        gone = tuple(i for i, k in old.items() if new.get(i) != k)
        return fresh, gone

    def summary(self) -> str:
        """One line for the page: the revision, the objects, what is carried by what."""
        if self.revision == NO_REVISION:
            return "no kept scene"
        free = sum(1 for i in self.items if not i.carried or i.fixed)
        fixed = [f"{i.id} on {i.link}" for i in self.items if i.fixed]
        carried = [f"{i.id} by {i.link}" for i in self.items if i.carried and not i.fixed]
        text = f"revision {self.revision}: {free} object(s)"
        if self.clouds:
            text += ", clouds: " + ", ".join(f"{c.id} ({len(c.points)} cells)"
                                             for c in self.clouds)
        if fixed:
            text += ", fixed to links: " + ", ".join(fixed)
        if carried:
            text += ", carried: " + ", ".join(carried)
        return text + (f" ({self.source})" if self.source else "")


def _item(shape: Obstacle, link: str | None, data: Mapping[str, Any], *,
          fixed: bool = False) -> SceneItem:
    mesh = obstacle_mesh(shape)
    key = hashlib.sha256(orjson.dumps({"link": link, "data": data},
                                      option=orjson.OPT_SORT_KEYS | orjson.OPT_SERIALIZE_NUMPY)
                         ).hexdigest()
    return SceneItem(shape.id, link, shape.pose(),
                     np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.uint32),
                     key, fixed)


def read_scene_file(path: str, description: Description) -> ViewerScene:
    """A scene file (``arduinobot scene save``; see :meth:`ViewerScene.from_json`).

    Raises:
        arduinobot.contract.errors.InvalidRequest: unreadable, not a scene, or an object the service
            would refuse (the message names the file).
    """
    from arduinobot.contract.errors import InvalidRequest
    from arduinobot.service.scene.file import SceneFile

    data = SceneFile(path).load()
    if data is None:
        raise InvalidRequest(f"no scene file {path}", field="scene")
    try:
        return ViewerScene.from_json(data, description, source=Path(path).name)
    except InvalidRequest as e:
        raise InvalidRequest(f"scene file {path}: {e.message}", details=e.details) from None




def world_points(items: Sequence[SceneItem], link_pose: Mapping[str, np.ndarray]
                 ) -> list[np.ndarray]:
    """Each item's vertices in the world, shape (n, 3) each (``link_pose``: link name ->
    its pose, shape (4, 4), for carried items)."""
    out = []
    for i in items:
        t = i.pose(link_pose.get(i.link) if i.link is not None else None)
        out.append(i.vertices @ t[:3, :3].T + t[:3, 3])
    return out
