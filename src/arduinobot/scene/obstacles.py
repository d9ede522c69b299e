"""Scene obstacles: boxes, spheres, cylinders and meshes placed in the world frame.

An :class:`Obstacle` is validated when it is built, so a bad request fails with the
field that is wrong (``obstacles[2].size``) before any collision object exists.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal, SupportsFloat, SupportsIndex, cast

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.model import Origin

if TYPE_CHECKING:  # numba: not for a client that only parses obstacles
    from arduinobot.planner.kinematics.dynamics import Payload

ShapeKind = Literal["box", "sphere", "cylinder", "mesh"]
_KINDS = ("box", "sphere", "cylinder", "mesh")


def _finite_vec(value: object, n: int, field: str, *, positive: bool = False) -> tuple[float, ...]:
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


def _positive(value: object, field: str) -> float:
    if not isinstance(value, (str, SupportsFloat, SupportsIndex)):  # what float() takes
        raise InvalidRequest(f"{value!r} is not a number", field=field)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidRequest(f"{value!r} is not a number", field=field) from None
    if not math.isfinite(v) or v <= 0:
        raise InvalidRequest(f"{value!r} must be a finite number > 0 [m]", field=field)
    return v


@dataclass(frozen=True)
class Obstacle:
    """One obstacle of the scene.

    Attributes:
        id: a unique name, used in colliding pairs (``("horizontal_arm", "table")``).
        shape: box, sphere, cylinder or mesh.
        size: box edge lengths (x, y, z) [m], centred on the pose.
        radius: sphere or cylinder radius [m].
        length: cylinder length along its z axis [m], centred on the pose.
        mesh_path: a mesh file (STL, OBJ, ...) in metres, in the obstacle frame.
        xyz: position [m] in the world frame.
        rpy: URDF roll-pitch-yaw [rad].
        where: the field prefix named in errors (e.g. ``obstacles[2]``).
    """

    id: str
    shape: ShapeKind
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None
    mesh_path: str | None = None
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    where: str = "obstacle"

    def __post_init__(self) -> None:
        w = self.where
        if not isinstance(self.id, str) or not self.id:
            raise InvalidRequest("must be a non-empty string", field=f"{w}.id")
        if self.shape not in _KINDS:
            raise InvalidRequest(f"'{self.shape}' is not one of {', '.join(_KINDS)}",
                                 field=f"{w}.shape")
        set_ = object.__setattr__
        set_(self, "xyz", _finite_vec(self.xyz, 3, f"{w}.xyz"))
        set_(self, "rpy", _finite_vec(self.rpy, 3, f"{w}.rpy"))
        if self.shape == "box":
            if self.size is None:
                raise InvalidRequest("a box needs size (x, y, z) [m]", field=f"{w}.size")
            set_(self, "size", _finite_vec(self.size, 3, f"{w}.size", positive=True))
        elif self.shape == "sphere":
            set_(self, "radius", _positive(self.radius, f"{w}.radius"))
        elif self.shape == "cylinder":
            set_(self, "radius", _positive(self.radius, f"{w}.radius"))
            set_(self, "length", _positive(self.length, f"{w}.length"))
        else:
            if not self.mesh_path or not Path(self.mesh_path).is_file():
                raise InvalidRequest(f"mesh file {self.mesh_path!r} does not exist",
                                     field=f"{w}.mesh_path")

    def pose(self) -> np.ndarray:
        """The obstacle's pose in the world frame, shape (4, 4)."""
        return Origin(xyz=self.xyz, rpy=self.rpy).matrix()

    @classmethod
    def from_mapping(cls, data: object, *, where: str = "obstacle") -> Obstacle:
        """Build from a JSON-like mapping (the service's wire format); anything else is
        refused with InvalidRequest."""
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object", field=where)
        known = {"id", "shape", "size", "radius", "length", "mesh_path", "xyz", "rpy"}
        extra = sorted(set(data) - known)
        if extra:
            raise InvalidRequest(f"unknown field(s) {', '.join(extra)}", field=where)
        for key in ("id", "shape"):
            if key not in data:
                raise InvalidRequest("is required", field=f"{where}.{key}")
        return cls(where=where, **{k: v for k, v in data.items()})


def validate_obstacles(obstacles: Sequence[Obstacle], *,
                       link_names: Sequence[str] = ()) -> tuple[Obstacle, ...]:
    """Check ids are unique and do not shadow a link name; returns them as a tuple."""
    seen: set[str] = set()
    links = set(link_names)
    for i, o in enumerate(obstacles):
        if not isinstance(o, Obstacle):
            raise InvalidRequest(f"expected an Obstacle, got {type(o).__name__}",
                                 field=f"obstacles[{i}]")
        if o.id in seen:
            raise InvalidRequest(f"duplicate id '{o.id}'", field=f"obstacles[{i}].id")
        if o.id in links:
            raise InvalidRequest(f"id '{o.id}' is also a link name", field=f"obstacles[{i}].id")
        seen.add(o.id)
    return tuple(obstacles)


def _box_unit(size: np.ndarray) -> np.ndarray:
    x, y, z = np.asarray(size, float) ** 2
    return np.diag([y + z, x + z, x + y]) / 12.0


def _unit_inertia(o: Obstacle) -> tuple[np.ndarray, np.ndarray]:
    """A shape's centroid (its frame) and its inertia per kg about it [m^2], as a uniform
    solid."""
    if o.shape == "box":
        return np.zeros(3), _box_unit(np.asarray(o.size))
    if o.shape == "sphere":
        assert o.radius is not None  # Obstacle checks every shape's dimensions
        return np.zeros(3), np.eye(3) * 0.4 * o.radius ** 2
    if o.shape == "cylinder":
        assert o.radius is not None and o.length is not None
        r2, l2 = o.radius ** 2, o.length ** 2
        return np.zeros(3), np.diag([(3 * r2 + l2) / 12, (3 * r2 + l2) / 12, r2 / 2])
    import trimesh  # only a mesh needs it

    mesh = cast(trimesh.Trimesh, trimesh.load(o.mesh_path, force="mesh"))
    if mesh.is_watertight and mesh.volume > 0:
        return (np.asarray(mesh.center_mass, float),
                np.asarray(mesh.moment_inertia, float) / float(mesh.mass))
    lo, hi = mesh.bounds
    return (lo + hi) / 2, _box_unit(hi - lo)


@dataclass(frozen=True)
class AttachedObject:
    """An object the robot carries: ``shape`` posed in ``link``'s frame (its ``xyz``/``rpy``
    are relative to the link, not the world), moving with the link.

    It is checked against the scene and every robot link except ``touch_links`` (empty:
    the links of the group that holds it, e.g. the gripper's), and its ``mass`` [kg] at
    ``com`` (in the link's frame [m]; None: the shape's centroid) enters the inverse
    dynamics of the effort-limited timing and the verifier.
    """

    shape: Obstacle
    link: str
    touch_links: tuple[str, ...] = ()
    mass: float = 0.0
    com: tuple[float, float, float] | None = None
    where: str = "attached"

    def __post_init__(self) -> None:
        if not isinstance(self.shape, Obstacle):
            raise InvalidRequest("must be an Obstacle", field=f"{self.where}.shape")
        if not isinstance(self.link, str) or not self.link:
            raise InvalidRequest(f"{self.link!r} is not a link name", field=f"{self.where}.link")
        if not isinstance(self.touch_links, tuple) or \
                not all(isinstance(t, str) for t in self.touch_links):
            raise InvalidRequest("must be a tuple of link names", field=f"{self.where}.touch_links")
        if isinstance(self.mass, bool) or not isinstance(self.mass, (int, float)) \
                or not math.isfinite(self.mass) or self.mass < 0:
            raise InvalidRequest(f"{self.mass!r} must be a finite mass >= 0 [kg]",
                                 field=f"{self.where}.mass")
        if self.com is not None:
            object.__setattr__(self, "com", _finite_vec(self.com, 3, f"{self.where}.com"))

    @property
    def id(self) -> str:
        return self.shape.id

    def payload(self) -> Payload:
        """Its mass at its centre of mass (``com``, else the shape's centroid) with the
        shape's inertia as a uniform solid (a mesh that is not closed: its bounding
        box's), all in the link's frame, for :meth:`.InverseDynamics.with_payloads`."""
        from arduinobot.planner.kinematics.dynamics import Payload

        centroid, inertia = _unit_inertia(self.shape)
        pose = self.shape.pose()
        rot = pose[:3, :3]
        com = np.asarray(self.com, float) if self.com is not None \
            else rot @ centroid + pose[:3, 3]
        tensor = self.mass * (rot @ inertia @ rot.T)
        c = [float(v) for v in com]
        t = [(float(r[0]), float(r[1]), float(r[2])) for r in tensor]
        return Payload(self.link, float(self.mass), (c[0], c[1], c[2]), (t[0], t[1], t[2]))

    def shape_key(self) -> tuple:
        """What its geometry and placement are (``where`` only names fields in errors)."""
        o = self.shape
        return (o.id, o.shape, o.size, o.radius, o.length, o.mesh_path, o.xyz, o.rpy,
                self.link, self.touch_links)

    def payload_key(self) -> tuple:
        """What its inverse dynamics depends on."""
        o = self.shape
        return (self.link, self.mass, self.com, o.shape, o.size, o.radius, o.length,
                o.mesh_path, o.xyz, o.rpy)

    @classmethod
    def from_mapping(cls, data: object, *, where: str = "attached") -> AttachedObject:
        """Build from the wire format ``{"object": {obstacle...}, "link": name,
        "touch_links": [...], "mass": kg, "com": [x, y, z]}``; the object's pose is in
        the link's frame."""
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object", field=where)
        extra = sorted(set(data) - {"object", "link", "touch_links", "mass", "com"})
        if extra:
            raise InvalidRequest(f"unknown field(s) {', '.join(extra)}", field=where)
        for key in ("object", "link"):
            if key not in data:
                raise InvalidRequest("is required", field=f"{where}.{key}")
        touch = data.get("touch_links", [])
        if not isinstance(touch, (list, tuple)) or not all(isinstance(t, str) for t in touch):
            raise InvalidRequest("must be a list of link names", field=f"{where}.touch_links")
        mass = data.get("mass", 0.0)
        if isinstance(mass, bool) or not isinstance(mass, (int, float)):
            raise InvalidRequest(f"{mass!r} must be a finite mass >= 0 [kg]",
                                 field=f"{where}.mass")
        return cls(Obstacle.from_mapping(data["object"], where=f"{where}.object"),
                   data["link"], tuple(touch), float(mass), data.get("com"), where=where)

    def to_mapping(self) -> dict:
        """The wire format (see :meth:`from_mapping`)."""
        o = self.shape
        obj: dict = {"id": o.id, "shape": o.shape, "xyz": list(o.xyz), "rpy": list(o.rpy)}
        for k in ("size", "radius", "length", "mesh_path"):
            v = getattr(o, k)
            if v is not None:
                obj[k] = list(v) if isinstance(v, tuple) else v
        out: dict = {"object": obj, "link": self.link, "touch_links": list(self.touch_links),
                     "mass": self.mass}
        if self.com is not None:
            out["com"] = list(self.com)
        return out


def default_touch_links(description: object, link: str) -> tuple[str, ...]:
    """The links an object held by ``link`` may touch: ``link`` and, when it belongs to
    an SRDF end effector (its group's links or its parent link), every link of that end
    effector (the gripper's claw support and fingers); without one, ``link`` and every
    link below it (what holds an object is its link's subtree)."""
    robot = description.robot  # type: ignore[attr-defined]
    srdf = getattr(description, "srdf", None)
    touch = [link]
    if srdf is not None:
        for e in srdf.end_effectors:
            group = srdf.groups.get(e.group)
            members = (e.parent_link, *(group.links if group else ()))
            if link in members:
                touch += [m for m in members if m not in touch]
        if len(touch) > 1:
            return tuple(touch)
    stack = [link]
    while stack:
        for j in robot.child_joints.get(stack.pop(), ()):
            if j.child not in touch:
                touch.append(j.child)
                stack.append(j.child)
    return tuple(touch)


def rigid_links(description: object, link: str) -> tuple[str, ...]:
    """``link`` and every link joined to it by fixed joints (up and down the tree): one
    rigid body, whose parts never move relative to an object fixed in ``link``'s frame, so
    their contact with it is the same in every state (what an object in a link's frame
    may touch)."""
    robot = description.robot  # type: ignore[attr-defined]
    out, stack = [link], [link]
    while stack:
        at = stack.pop()
        near = [j.child for j in robot.child_joints.get(at, ()) if j.type == "fixed"]
        up = robot.parent_joint.get(at)
        if up is not None and up.type == "fixed":
            near.append(up.parent)
        for n in near:
            if n not in out:
                out.append(n)
                stack.append(n)
    return tuple(out)


def resolve_attached(description: object, attached: Sequence[AttachedObject], *,
                     obstacles: Sequence[Obstacle] = (), field: str = "attached"
                     ) -> tuple[AttachedObject, ...]:
    """Check ``attached`` against the robot (each link exists, touch links exist, ids
    unique and unlike any link or obstacle) and give each without touch links the
    default ones (:func:`default_touch_links`). Errors name ``field[i]...``."""
    robot = description.robot  # type: ignore[attr-defined]
    if not isinstance(attached, (tuple, list)):
        raise InvalidRequest("must be a list of carried objects", field=field)
    seen = {o.id for o in obstacles}
    out = []
    for i, a in enumerate(attached):
        where = f"{field}[{i}]"
        if not isinstance(a, AttachedObject):
            raise InvalidRequest(f"expected an AttachedObject, got {type(a).__name__}",
                                 field=where)
        if a.link not in robot.links:
            raise InvalidRequest(f"'{a.link}' is not a link of the robot", field=f"{where}.link",
                                 details={"links": sorted(robot.links)})
        for t in a.touch_links:
            if t not in robot.links:
                raise InvalidRequest(f"'{t}' is not a link of the robot",
                                     field=f"{where}.touch_links")
        if a.id in robot.links:
            raise InvalidRequest(f"id '{a.id}' is also a link name", field=f"{where}.object.id")
        if a.id in seen:
            raise InvalidRequest(f"duplicate id '{a.id}'", field=f"{where}.object.id")
        seen.add(a.id)
        touch = a.touch_links or default_touch_links(description, a.link)
        out.append(a if touch == a.touch_links else
                   AttachedObject(a.shape, a.link, touch, a.mass, a.com, where=a.where))
    return tuple(out)
