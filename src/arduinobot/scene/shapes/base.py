"""The base of every shape: what a shape answers (:class:`Shape`), and the geometry
helpers its kinds share (FCL and trimesh loaded on first use, a box's inertia, a point
inside a convex hull)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

import numpy as np

from arduinobot.contract.errors import InvalidRequest, unknown_names

if TYPE_CHECKING:  # both only for the methods that build geometry, not to parse a shape
    import fcl
    import trimesh


def box_unit_inertia(size: Sequence[float] | np.ndarray) -> np.ndarray:
    """A uniform solid box's inertia per kg about its centre [m^2], shape (3, 3)."""
    x, y, z = np.asarray(size, float) ** 2
    return np.diag([y + z, x + z, x + y]) / 12.0


S = TypeVar("S", bound="Shape")


@dataclass(frozen=True)
class Shape(ABC):
    """A solid in its own frame [m]. Subclasses are frozen dataclasses whose fields are
    their JSON dimension fields; ``where`` (not a field of theirs) names them in errors.

    Class attributes:
        kind: its JSON ``shape`` name.
        cli_form: its dimensions on the command line (``"sx,sy,sz"``); None: it has none
            (a mesh file).
        portable: it means the same to another process (a file path does not).
        inline: the fields a kept-scene object sends in place of its file (a mesh's
            ``mesh`` and ``scale``), see :meth:`stored`.
    """

    kind: ClassVar[str]
    cli_form: ClassVar[str | None] = None
    portable: ClassVar[bool] = True
    inline: ClassVar[tuple[str, ...]] = ()
    has_surface: ClassVar[bool] = False

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """Its JSON dimension fields, in order."""
        names = _FIELD_NAMES.get(cls)
        if names is None:  # once a class: dataclasses.fields is slow in a request's loop
            names = _FIELD_NAMES[cls] = tuple(f.name for f in fields(cls))
        return names

    @classmethod
    def from_json(cls: type[S], data: Mapping[str, Any], *, where: str) -> S:
        """Build from its dimension fields (``data`` may hold no other key), checked;
        errors name ``<where>.<field>``."""
        extra = sorted(set(data) - set(cls.field_names()))
        if extra:
            raise InvalidRequest(f"unknown field(s) {unknown_names(extra, cls.field_names())} "
                                 f"for a {cls.kind} (it takes {', '.join(cls.field_names())})",
                                 field=where)
        return cls(**{k: cls._checked(k, data.get(k), f"{where}.{k}")
                      for k in cls.field_names()})

    @classmethod
    @abstractmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        """Field ``name``'s ``value`` validated and normalised (``field`` for errors)."""

    @classmethod
    def from_numbers(cls: type[S], values: Sequence[float], *, where: str) -> S:
        """Build from the numbers of its :attr:`cli_form`, checked."""
        if cls.cli_form is None:
            raise InvalidRequest(f"a {cls.kind} has no numeric form", field=f"{where}.shape")
        n = len(cls.cli_form.split(","))
        if len(values) != n:
            raise InvalidRequest(f"{cls.cli_form} must be {n} numbers", field=where)
        return cls.from_json(cls.json_of_numbers(values), where=where)

    @classmethod
    def json_of_numbers(cls, values: Sequence[float]) -> dict[str, Any]:
        """Its dimension fields from the numbers of its :attr:`cli_form` (unchecked)."""
        raise InvalidRequest(f"a {cls.kind} has no numeric form", field="shape")

    @classmethod
    def stored(cls, data: Mapping[str, Any], *, where: str, folder: Path) -> dict[str, Any]:
        """A kept-scene object's fields (``data``, its wire form) with its :attr:`inline`
        payload written to a content-addressed file in ``folder`` and named by its
        dimension field; a shape without one: ``data`` as is."""
        return dict(data)

    @classmethod
    def summary(cls, data: Mapping[str, Any]) -> str:
        """Its dimensions in words, from its wire form ``data`` (as a listing prints
        them: ``size 1,1,0.1``)."""
        return " ".join(f"{k} " + (",".join(f"{x:g}" for x in v) if isinstance(v, list)
                                   else f"{v:g}")
                        for k in cls.field_names() if (v := data.get(k)) is not None)

    def to_json(self) -> dict[str, Any]:
        """Its dimension fields (tuples as lists), as :meth:`from_json` reads them."""
        return {k: list(v) if isinstance(v, tuple) else v
                for k in self.field_names() if (v := getattr(self, k)) is not None}

    def key(self) -> tuple:
        """What it is as written (kind and dimensions; a mesh: its path)."""
        key = self.__dict__.get("_key")
        if key is None:  # built once: a world cache looks up every obstacle's per request
            key = self.__dict__["_key"] = (self.kind, *[getattr(self, k)
                                                        for k in self.field_names()])
        return key

    def content_key(self) -> tuple:
        """What its geometry depends on (a mesh: its file's bytes, hashed)."""
        return self.key()

    @property
    def source(self) -> Path | None:
        """The file its triangles are read from; None: made from its dimensions."""
        return None

    @property
    def source_scale(self) -> tuple[float, float, float]:
        """The per-axis scale [-] applied to :attr:`source`'s coordinates."""
        return (1.0, 1.0, 1.0)

    @abstractmethod
    def triangles(self) -> trimesh.Trimesh:
        """Its surface as triangles in its frame [m] (for display, hulls, trees): a new
        mesh each call, the caller's to move."""

    def unit_inertia(self) -> tuple[np.ndarray, np.ndarray]:
        """Its centroid shape (3,) [m] and inertia per kg about it shape (3, 3) [m^2],
        as a uniform solid, in its frame."""
        return np.zeros(3), self._unit_inertia()

    def _unit_inertia(self) -> np.ndarray:
        raise NotImplementedError

    def half_extents(self) -> np.ndarray | None:
        """Half the sides of the box around it, centred on its frame [m], shape (3,);
        None: read its triangles for a tighter box tree."""
        return None

    def reach(self) -> float:
        """The farthest its surface reaches from its frame's origin [m] (a bounding
        sphere's radius about it); a mesh: its farthest vertex."""
        v = np.asarray(self.triangles().vertices, float)
        return float(np.sqrt(np.einsum("ij,ij->i", v, v).max()))

    def hull_points(self) -> tuple[np.ndarray, float] | None:
        """Points shape (m, 3) [m] and a radius [m]: it is within the radius of their
        convex hull; None: the convex hull of its triangles (cached by the planner)."""
        return None

    @abstractmethod
    def collision_geometry(self) -> fcl.CollisionGeometry:
        """FCL's geometry of it, in its frame."""

    def surface(self) -> trimesh.Trimesh | None:
        """A closed primitive's surface for distances that must see its inside (FCL
        reads a point in a primitive solid as touching); None: not needed (then
        :attr:`has_surface` is False, read without building anything)."""
        return None

    def mjcf(self) -> tuple[str, str] | None:
        """Its MuJoCo geom ``(type, size)`` [m]; None: convex pieces of :attr:`source`."""
        return None

    def grown(self, margin: float) -> Shape:
        """This shape grown by ``margin`` [m] on every side (shrunk when negative): a
        padding of uncertainty put on, or taken off.

        Raises:
            InvalidRequest: a shape that cannot be grown (a mesh file), or shrunk to
                nothing.
        """
        raise InvalidRequest(f"a {self.kind} cannot be grown or shrunk by a margin",
                             field="shape")

    def contains(self, points: np.ndarray, padding: float = 0.0) -> np.ndarray:
        """Which ``points`` (shape (n, 3) [m], in the shape's frame) lie inside it grown by
        ``padding`` [m]: shape (n,) bool. A mesh counts as its convex hull (a superset)."""
        hull = self.hull_points()
        if hull is None:  # the hull of its triangles
            return inside_hull(points, np.asarray(self.triangles().vertices), padding)
        return inside_hull(points, hull[0], hull[1] + padding)




_FIELD_NAMES: dict[type, tuple[str, ...]] = {}


def fcl_module() -> Any:
    """The ``fcl`` module, imported on first use (only a collision world needs it)."""
    import fcl

    return fcl


def bvh(mesh: trimesh.Trimesh) -> fcl.BVHModel:
    """FCL's bounding-volume tree of ``mesh``'s triangles."""
    m = fcl_module().BVHModel()
    m.beginModel(len(mesh.vertices), len(mesh.faces))
    m.addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
    m.endModel()
    return m


def creation() -> Any:
    """``trimesh.creation``, imported on first use."""
    import trimesh.creation

    return trimesh.creation


def inside_hull(points: np.ndarray, vertices: np.ndarray, margin: float) -> np.ndarray:
    """Which ``points`` lie inside the convex hull of ``vertices`` grown by ``margin`` [m]
    (each facet pushed out); a flat set of vertices: their box grown by ``margin``."""
    from scipy.spatial import ConvexHull, QhullError

    v = np.asarray(vertices, dtype=np.float64)
    try:
        eq = ConvexHull(v).equations
    except QhullError:
        lo, hi = v.min(axis=0) - margin, v.max(axis=0) + margin
        return np.asarray(((points >= lo) & (points <= hi)).all(axis=1))
    return np.asarray((points @ eq[:, :3].T + eq[:, 3] <= margin).all(axis=1))
