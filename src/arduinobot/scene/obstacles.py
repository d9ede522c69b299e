"""Scene obstacles (shapes, :mod:`.shapes`, placed in the world frame) and the objects
the robot carries.

An :class:`Obstacle` is validated when it is built, so a bad request fails with the
field that is wrong (``obstacles[2].size``) before any collision object exists.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.contract.errors import InvalidRequest, unknown_fields
from arduinobot.scene.payload import Payload
from arduinobot.scene.pose import rpy_matrix
from arduinobot.scene.shapes import Shape, dimension_fields, finite_vec, shape_class


@dataclass(frozen=True, init=False)
class Obstacle:
    """One obstacle of the scene: a shape placed in the world frame.

    Built as ``Obstacle("table", "box", size=(1, 1, 0.1), xyz=...)`` (the shape's name and
    its dimension fields, :mod:`.shapes`) or ``Obstacle("table", Box((1, 1, 0.1)))``; its
    dimensions read through it (``o.size``; None when its shape has no such field).

    Attributes:
        id: a unique name, used in colliding pairs (``("horizontal_arm", "table")``).
        geometry: its shape (:class:`.shapes.Shape`), in the obstacle's frame.
        xyz: position [m] in the world frame.
        rpy: URDF roll-pitch-yaw [rad].
        where: the field prefix named in errors (e.g. ``obstacles[2]``).
    """

    id: str
    geometry: Shape
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    where: str

    def __init__(self, id: str, shape: str | Shape | None = None, *,
                 xyz: Sequence[float] = (0.0, 0.0, 0.0), rpy: Sequence[float] = (0.0, 0.0, 0.0),
                 where: str = "obstacle", geometry: Shape | None = None, **dims: object) -> None:
        w = where
        if not isinstance(id, str) or not id:
            raise InvalidRequest("must be a non-empty string", field=f"{w}.id")
        given = geometry if geometry is not None else shape
        cls = type(given) if isinstance(given, Shape) else shape_class(given, field=f"{w}.shape")
        set_ = object.__setattr__
        set_(self, "id", id)
        set_(self, "xyz", finite_vec(xyz, 3, f"{w}.xyz"))
        set_(self, "rpy", finite_vec(rpy, 3, f"{w}.rpy"))
        set_(self, "where", where)
        if isinstance(given, Shape):
            if dims:
                raise InvalidRequest(f"unknown field(s) {', '.join(sorted(dims))}", field=w)
            set_(self, "geometry", given)
        else:
            set_(self, "geometry", cls.from_json(
                {k: v for k, v in dims.items() if v is not None}, where=w))

    def __getattr__(self, name: str) -> Any:
        # a shape's dimension read through the obstacle (o.size); only called when normal
        # lookup failed, so never for id, geometry, xyz, rpy (guarded while unpickling)
        if name.startswith("_") or "geometry" not in self.__dict__:
            raise AttributeError(name)
        g = self.__dict__["geometry"]
        if name in g.field_names():
            return getattr(g, name)
        if name in dimension_fields():
            return None
        raise AttributeError(f"'Obstacle' object has no attribute '{name}'")

    @property
    def shape(self) -> str:
        """Its shape's name (``box``, ``sphere``, ...)."""
        return self.geometry.kind

    def pose(self) -> np.ndarray:
        """The obstacle's pose in the world frame, shape (4, 4)."""
        t = np.eye(4)
        t[:3, :3] = rpy_matrix(self.rpy)
        t[:3, 3] = self.xyz
        return t

    def key(self) -> tuple:
        """What it is and where (``where`` only names fields in errors)."""
        return (self.id, self.geometry.key(), self.xyz, self.rpy)

    def to_json(self) -> dict[str, Any]:
        """The requests' form (plan_request.json's ``obstacles``)."""
        return {"id": self.id, "shape": self.shape, **self.geometry.to_json(),
                "xyz": list(self.xyz), "rpy": list(self.rpy)}

    @classmethod
    def from_mapping(cls, data: object, *, where: str = "obstacle",
                     files: bool = True) -> Obstacle:
        """Build from a JSON-like mapping (the service's wire format); anything else is
        refused with InvalidRequest.

        Args:
            files: whether it may name a file of this machine (a mesh's ``mesh_path``:
                a shape that is not :attr:`~arduinobot.scene.shapes.Shape.portable`).
                False for anything from the wire: a path from a client would read any
                file the server can, past every mesh cap, and tell whether it exists.
        """
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object", field=where)
        for key in ("id", "shape"):
            if key not in data:
                raise InvalidRequest("is required", field=f"{where}.{key}")
        extra = sorted(set(data) - _PLACED - dimension_fields())
        if extra:
            raise InvalidRequest(unknown_fields(extra, _PLACED | dimension_fields(),
                                                of="an obstacle"), field=where)
        if not files:
            refuse_files(data, where=where)
        return cls(where=where, **{k: v for k, v in data.items()})

    from_json = from_mapping


_PLACED = frozenset({"id", "shape", "xyz", "rpy"})  # an obstacle's own fields; the rest: its shape's


def refuse_files(data: Mapping[str, Any], *, where: str) -> None:
    """Refuse an obstacle's wire form ``data`` that names a file of this machine (a
    shape that is not portable: a mesh's ``mesh_path``), before anything looks at the
    file: the refusal neither echoes the path nor tells whether it exists."""
    cls = shape_class(data.get("shape"), field=f"{where}.shape")
    if cls.portable:
        return
    names = cls.field_names()
    raise InvalidRequest(
        f"a {cls.kind} is not read from a file of the server: send it inline to the "
        "kept scene (<prefix>/scene/apply, its mesh {format, data}) and name it there",
        field=f"{where}.{names[0] if names else 'shape'}")


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
            object.__setattr__(self, "com", finite_vec(self.com, 3, f"{self.where}.com"))

    @property
    def id(self) -> str:
        return self.shape.id

    def payload(self) -> Payload:
        """Its mass at its centre of mass (``com``, else the shape's centroid) with the
        shape's inertia as a uniform solid (a mesh that is not closed: its bounding
        box's), all in the link's frame, for :meth:`.InverseDynamics.with_payloads`."""

        centroid, inertia = self.shape.geometry.unit_inertia()
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
        return (self.shape.key(), self.link, self.touch_links)

    def payload_key(self) -> tuple:
        """What its inverse dynamics depends on."""
        o = self.shape
        return (self.link, self.mass, self.com, o.geometry.key(), o.xyz, o.rpy)

    @classmethod
    def from_mapping(cls, data: object, *, where: str = "attached") -> AttachedObject:
        """Build from the wire format ``{"object": {obstacle...}, "link": name,
        "touch_links": [...], "mass": kg, "com": [x, y, z]}``; the object's pose is in
        the link's frame."""
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object", field=where)
        known = {"object", "link", "touch_links", "mass", "com"}
        extra = sorted(set(data) - known)
        if extra:
            raise InvalidRequest(unknown_fields(extra, known, of="an attached object"),
                                 field=where)
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
        out: dict = {"object": self.shape.to_json(), "link": self.link, "touch_links": list(self.touch_links),
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
