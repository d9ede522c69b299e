"""The shapes of the scene: one frozen class per kind, each the only place that knows its
dimensions.

A shape validates itself (errors name ``<where>.<field>``), reads and writes its JSON
dimension fields (the ``shape`` name and the pose belong to the obstacle), gives its key
(what it is as written) and content key (what its geometry depends on), its triangles,
its unit inertia, its collision geometry, its MuJoCo geom and its command-line form.
Consumers ask the shape; none switches on its kind.

A new kind (a point cloud) is one new class here plus its :func:`register` line.
"""

from __future__ import annotations

import hashlib
import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, SupportsFloat, SupportsIndex, TypeVar, cast

import numpy as np

from arduinobot.contract.errors import InvalidRequest, unknown_names

if TYPE_CHECKING:  # both only for the methods that build geometry, not to parse a shape
    import fcl
    import trimesh

_SPHERE_SUBDIVISIONS = 3  # the icosphere drawn for a sphere (as description.meshes)
_CYLINDER_SECTIONS = 48
# sides of the prism that stands in for a cylinder's hull (circumscribed: it holds the
# cylinder, so its support is never short of the cylinder's)
_PRISM_SIDES = 24


def finite_vec(value: object, n: int, field: str, *, positive: bool = False
               ) -> tuple[float, ...]:
    """``value`` as ``n`` finite floats (``positive``: each > 0), else InvalidRequest
    naming ``field``."""
    if not isinstance(value, Iterable):
        raise InvalidRequest(f"{value!r} must be {n} numbers", field=field)
    try:
        vec = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise InvalidRequest(f"{value!r} must be {n} numbers", field=field) from None
    if len(vec) != n or not all(math.isfinite(v) for v in vec):
        raise InvalidRequest(f"{value!r} must be {n} finite numbers", field=field)
    if positive and any(v <= 0 for v in vec):
        raise InvalidRequest(f"{value!r} must be > 0 [m]", field=field)
    return vec


def positive(value: object, field: str) -> float:
    """``value`` as a finite float > 0, else InvalidRequest naming ``field``."""
    if not isinstance(value, (str, SupportsFloat, SupportsIndex)):  # what float() takes
        raise InvalidRequest(f"{value!r} is not a number", field=field)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidRequest(f"{value!r} is not a number", field=field) from None
    if not math.isfinite(v) or v <= 0:
        raise InvalidRequest(f"{value!r} must be a finite number > 0 [m]", field=field)
    return v


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

    @abstractmethod
    def triangles(self) -> trimesh.Trimesh:
        """Its surface as triangles in its frame [m] (for display, hulls, trees)."""

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
            return _inside_hull(points, np.asarray(self.triangles().vertices), padding)
        return _inside_hull(points, hull[0], hull[1] + padding)


_SHAPES: dict[str, type[Shape]] = {}
_FIELD_NAMES: dict[type, tuple[str, ...]] = {}
_DIMENSIONS: list[frozenset[str]] = [frozenset()]  # every shape's fields, kept by register


def register(cls: type[S]) -> type[S]:
    """Add a shape class to the registry under its ``kind`` (a class decorator)."""
    if cls.kind in _SHAPES:
        raise ValueError(f"shape kind '{cls.kind}' is registered twice")
    _SHAPES[cls.kind] = cls
    _DIMENSIONS[0] = _DIMENSIONS[0] | set(cls.field_names())
    return cls


def kinds() -> tuple[str, ...]:
    """Every registered shape name, in registration order."""
    return tuple(_SHAPES)


def shape_class(kind: object, *, field: str = "shape") -> type[Shape]:
    """The class registered under ``kind``, else InvalidRequest naming ``field``."""
    cls = _SHAPES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise InvalidRequest(f"'{kind}' is not one of {', '.join(_SHAPES)}", field=field)
    return cls


def dimension_fields() -> frozenset[str]:
    """Every dimension field of any registered shape."""
    return _DIMENSIONS[0]


def of_geometry(geometry: Any) -> Shape | None:
    """A URDF geometry (:class:`arduinobot.description.model.Geometry`) as its shape when
    its kind's dimension fields are the geometry's own (box, sphere, cylinder); None
    otherwise (a mesh: a file and a scale, read as the link's)."""
    cls = _SHAPES.get(geometry.kind)
    if cls is None or not all(hasattr(geometry, f) for f in cls.field_names()):
        return None
    return cls.from_json({f: getattr(geometry, f) for f in cls.field_names()},
                         where="geometry")


def check_inline(cls: type[Shape], data: Mapping[str, Any], *, where: str) -> None:
    """Refuse an inline field (:attr:`Shape.inline`) that ``cls`` does not take."""
    for key in sorted({k for c in _SHAPES.values() for k in c.inline} - set(cls.inline)):
        if key in data:
            owners = " or ".join(c.kind for c in _SHAPES.values() if key in c.inline)
            raise InvalidRequest(f"only a {owners} object takes it", field=f"{where}.{key}")


def _fcl() -> Any:
    import fcl  # only a collision world needs it

    return fcl


def _bvh(mesh: trimesh.Trimesh) -> fcl.BVHModel:
    m = _fcl().BVHModel()
    m.beginModel(len(mesh.vertices), len(mesh.faces))
    m.addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
    m.endModel()
    return m


def _creation() -> Any:
    import trimesh.creation

    return trimesh.creation


@register
@dataclass(frozen=True)
class Box(Shape):
    """A box centred on its frame; ``size`` its edge lengths (x, y, z) [m]."""

    size: tuple[float, float, float]
    kind: ClassVar[str] = "box"
    cli_form: ClassVar[str | None] = "sx,sy,sz"
    has_surface: ClassVar[bool] = True

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        if value is None:
            raise InvalidRequest("a box needs size (x, y, z) [m]", field=field)
        return finite_vec(value, 3, field, positive=True)

    @classmethod
    def json_of_numbers(cls, values: Sequence[float]) -> dict[str, Any]:
        return {"size": list(values)}

    def grown(self, margin: float) -> Box:
        return Box.from_json({"size": [x + 2 * margin for x in self.size]}, where="shape")

    def contains(self, points: np.ndarray, padding: float = 0.0) -> np.ndarray:
        half = np.asarray(self.size) / 2 + padding
        return np.asarray((np.abs(points) <= half).all(axis=1))

    def triangles(self) -> trimesh.Trimesh:
        return _creation().box(extents=self.size)

    def _unit_inertia(self) -> np.ndarray:
        return box_unit_inertia(self.size)

    def half_extents(self) -> np.ndarray:
        return np.asarray(self.size, float) / 2

    def hull_points(self) -> tuple[np.ndarray, float]:
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        return corners * self.half_extents(), 0.0

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return _fcl().Box(*self.size)

    def surface(self) -> trimesh.Trimesh:
        return self.triangles()

    def mjcf(self) -> tuple[str, str]:
        return "box", " ".join(repr(float(v)) for v in self.half_extents())


@register
@dataclass(frozen=True)
class Sphere(Shape):
    """A ball centred on its frame; ``radius`` [m]."""

    radius: float
    kind: ClassVar[str] = "sphere"
    cli_form: ClassVar[str | None] = "r"

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        return positive(value, field)

    @classmethod
    def json_of_numbers(cls, values: Sequence[float]) -> dict[str, Any]:
        return {"radius": values[0]}

    def grown(self, margin: float) -> Sphere:
        return Sphere.from_json({"radius": self.radius + margin}, where="shape")

    def contains(self, points: np.ndarray, padding: float = 0.0) -> np.ndarray:
        return np.asarray(np.einsum("ij,ij->i", points, points)
                          <= (self.radius + padding) ** 2)

    def triangles(self) -> trimesh.Trimesh:
        return _creation().icosphere(subdivisions=_SPHERE_SUBDIVISIONS, radius=self.radius)

    def _unit_inertia(self) -> np.ndarray:
        return np.eye(3) * 0.4 * self.radius ** 2

    def half_extents(self) -> np.ndarray:
        return np.full(3, self.radius)

    def hull_points(self) -> tuple[np.ndarray, float]:
        return np.zeros((1, 3)), float(self.radius)

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return _fcl().Sphere(self.radius)

    def mjcf(self) -> tuple[str, str]:
        return "sphere", repr(float(self.radius))


@register
@dataclass(frozen=True)
class Cylinder(Shape):
    """A cylinder along its frame's z axis, centred on it; ``radius`` and ``length`` [m]."""

    radius: float
    length: float
    kind: ClassVar[str] = "cylinder"
    cli_form: ClassVar[str | None] = "r,l"

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        return positive(value, field)

    @classmethod
    def json_of_numbers(cls, values: Sequence[float]) -> dict[str, Any]:
        return {"radius": values[0], "length": values[1]}

    def grown(self, margin: float) -> Cylinder:
        return Cylinder.from_json({"radius": self.radius + margin,
                                   "length": self.length + 2 * margin}, where="shape")

    def contains(self, points: np.ndarray, padding: float = 0.0) -> np.ndarray:
        radial = points[:, 0] ** 2 + points[:, 1] ** 2 <= (self.radius + padding) ** 2
        return np.asarray(radial & (np.abs(points[:, 2]) <= self.length / 2 + padding))

    def triangles(self) -> trimesh.Trimesh:
        return _creation().cylinder(radius=self.radius, height=self.length,
                                    sections=_CYLINDER_SECTIONS)

    def _unit_inertia(self) -> np.ndarray:
        r2, l2 = self.radius ** 2, self.length ** 2
        return np.diag([(3 * r2 + l2) / 12, (3 * r2 + l2) / 12, r2 / 2])

    def half_extents(self) -> np.ndarray:
        return np.array([self.radius, self.radius, self.length / 2])

    def hull_points(self) -> tuple[np.ndarray, float]:
        ang = 2 * np.pi * np.arange(_PRISM_SIDES) / _PRISM_SIDES
        r = self.radius / np.cos(np.pi / _PRISM_SIDES)
        ring = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
        return np.vstack([np.column_stack([ring, np.full(_PRISM_SIDES, z)])
                          for z in (-self.length / 2, self.length / 2)]), 0.0

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return _fcl().Cylinder(self.radius, self.length)

    def mjcf(self) -> tuple[str, str]:
        return "cylinder", f"{float(self.radius)!r} {0.5 * float(self.length)!r}"


@register
@dataclass(frozen=True)
class Mesh(Shape):
    """A mesh file (STL, OBJ, PLY, ...) in metres, in its frame; ``mesh_path`` on this
    machine (an inline mesh is written to one first: :mod:`.mesh_codec`)."""

    mesh_path: str
    kind: ClassVar[str] = "mesh"
    portable: ClassVar[bool] = False
    inline: ClassVar[tuple[str, ...]] = ("mesh", "scale")

    @classmethod
    def stored(cls, data: Mapping[str, Any], *, where: str, folder: Path) -> dict[str, Any]:
        if "mesh" not in data:
            raise InvalidRequest("a mesh object needs mesh {format, data}",
                                 field=f"{where}.mesh")
        from arduinobot.scene.mesh_codec import decode_mesh, scale_of

        mesh = decode_mesh(data["mesh"], scale=scale_of(data.get("scale"), f"{where}.scale"),
                           field=f"{where}.mesh")
        out = {k: v for k, v in data.items() if k not in cls.inline}
        out["mesh_path"] = str(mesh.write(folder))
        return out

    @classmethod
    def summary(cls, data: Mapping[str, Any]) -> str:
        if "mesh" not in data:  # a file of this machine's
            return f"mesh file {data.get('mesh_path')}"
        import base64

        size = len(base64.b64decode(data["mesh"]["data"]))
        return f"{data['mesh']['format']} mesh, {size} bytes, scale {data.get('scale', 1)}"

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        if not isinstance(value, str) or not value or not Path(value).is_file():
            raise InvalidRequest(f"mesh file {value!r} does not exist", field=field)
        return value

    def content_key(self) -> tuple:
        # the bytes: the same content under another name, or a file rewritten in place,
        # is told apart
        with open(self.mesh_path, "rb") as f:
            return ("mesh", hashlib.sha256(f.read()).digest())

    @property
    def source(self) -> Path:
        return Path(self.mesh_path)

    def triangles(self) -> trimesh.Trimesh:
        import trimesh

        return cast(trimesh.Trimesh, trimesh.load(self.mesh_path, force="mesh"))  # one mesh

    def unit_inertia(self) -> tuple[np.ndarray, np.ndarray]:
        mesh = self.triangles()
        if mesh.is_watertight and mesh.volume > 0:
            return (np.asarray(mesh.center_mass, float),
                    np.asarray(mesh.moment_inertia, float) / float(mesh.mass))
        lo, hi = mesh.bounds  # not closed: its bounding box's
        return (lo + hi) / 2, box_unit_inertia(hi - lo)

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return _bvh(self.triangles())


def _inside_hull(points: np.ndarray, vertices: np.ndarray, margin: float) -> np.ndarray:
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
