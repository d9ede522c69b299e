"""The planning scene that lasts (the kept scene's model): its objects at a revision, and
what a plan or check takes of it (:class:`SceneSnapshot`, :func:`with_scene`); how an
apply changes it is :mod:`arduinobot.scene.change`'s, how a wire object becomes one of
its objects :mod:`arduinobot.scene.builder`'s; its file on disk is
:mod:`arduinobot.service.scene.file`'s, its service :mod:`arduinobot.service.scene`.

A :class:`SceneState` is immutable: :func:`arduinobot.scene.change.apply` builds the next
one or raises, so a refused apply leaves the scene as it was by construction. Each object keeps its wire form
(what ``<prefix>/scene`` answers, meshes as sent) and its
:class:`~arduinobot.scene.obstacles.Obstacle` (a mesh as its content-addressed file, see
:mod:`arduinobot.scene.mesh_codec`), which is what plans and checks use. The sharing between
instances is :mod:`arduinobot.service.scene.sync`'s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from arduinobot.contract.errors import InvalidRequest, SceneConflict
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle

#: Most objects a scene holds (as many as a plan request's own obstacles).
MAX_SCENE_OBJECTS = 256
#: The frame a free object is placed in unless it names a link's (then it moves with that
#: link); a carried one is in its link's frame, see ``attach``.
WORLD = "world"
#: Where an apply's robot state came from (``state_source`` in its reply).
StateSource = Literal["request", "robot", "zero"]


@dataclass(frozen=True)
class SceneObject:
    """One object of the scene: ``data`` its wire form, ``obstacle`` its geometry (posed
    in the world, or in its ``link``'s frame: ``fixed``, the object as plans carry it)."""

    id: str
    data: Mapping[str, Any]
    obstacle: Obstacle
    fixed: AttachedObject | None = None

    @property
    def link(self) -> str | None:
        """The link whose frame it is fixed in (None: the world)."""
        return None if self.fixed is None else self.fixed.link


@dataclass(frozen=True)
class SceneCloud:
    """One point cloud of the scene (``shape: "points"``): ``data`` its wire form with the
    robot's ``state`` it was taken at, ``bodies`` its kept cells (and its shadow with
    ``unknown: "occupied"``), ``counts`` what became of its points (the apply reply's)."""

    id: str
    data: Mapping[str, Any]
    bodies: tuple[CloudObstacle, ...]
    counts: Mapping[str, Any]


@dataclass(frozen=True)
class SceneAttached:
    """One carried object: ``data`` its wire form (``{"object", "link", "touch_links",
    "mass", "com"}``, the object's xyz/rpy in the link's frame), ``attached`` what plans
    and checks carry."""

    id: str
    data: Mapping[str, Any]
    attached: AttachedObject


@dataclass(frozen=True)
class SceneSnapshot:
    """What a plan or check needs of the scene: its revision, obstacles (small: a mesh is
    a file path) and carried objects, sent with each job to a worker."""

    revision: int
    obstacles: tuple[Obstacle, ...] = ()
    attached: tuple[AttachedObject, ...] = ()
    #: the ids among ``attached`` that are objects fixed in a link's frame (not picked up)
    fixed: frozenset[str] = frozenset()
    #: the point clouds' cell bodies (sent once per revision: a worker holds the scene)
    clouds: tuple[CloudObstacle, ...] = ()
    #: each point cloud's id and what its unknown space was taken as ("free", "occupied")
    unknown: tuple[tuple[str, str], ...] = ()

    def assumptions(self) -> dict[str, str]:
        """``{cloud id: "free" | "occupied"}``: what a plan or check of this scene took
        the space its clouds' cameras did not see to be (what its reply says)."""
        return dict(self.unknown)


@dataclass(frozen=True)
class SceneState:
    """The scene at one revision (0: empty, never changed)."""

    revision: int = 0
    objects: tuple[SceneObject, ...] = ()
    attached: tuple[SceneAttached, ...] = ()
    clouds: tuple[SceneCloud, ...] = ()
    snapshot: SceneSnapshot = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # an object in a link's frame moves with its link: plans carry it (massless)
        object.__setattr__(self, "snapshot", SceneSnapshot(
            self.revision, tuple(o.obstacle for o in self.objects if o.fixed is None),
            tuple(a.attached for a in self.attached)
            + tuple(o.fixed for o in self.objects if o.fixed is not None),
            frozenset(o.id for o in self.objects if o.fixed is not None),
            tuple(b for c in self.clouds for b in c.bodies),
            tuple((c.id, str(c.data.get("unknown", "free"))) for c in self.clouds)))

    def to_json(self) -> dict[str, Any]:
        """The ``<prefix>/scene`` reply (and the scene file)."""
        return {"revision": self.revision,
                "objects": [dict(o.data) for o in self.objects]
                + [dict(c.data) for c in self.clouds],
                "attached": [dict(a.data) for a in self.attached]}

    def ids(self) -> tuple[str, ...]:
        return tuple(o.id for o in self.objects) + tuple(c.id for c in self.clouds)

    def attached_ids(self) -> tuple[str, ...]:
        return tuple(a.id for a in self.attached)


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
    ids = {o.id for o in snap.obstacles} | {a.id for a in snap.attached} \
        | {c.id for c in snap.clouds}
    for i, o in enumerate(own):
        if o.id in ids:
            raise InvalidRequest(f"id '{o.id}' is also an object of the kept scene (revision "
                                 f"{snap.revision})", field=f"obstacles[{i}].id")
    return snap.obstacles + own, snap.revision
