"""The robot model: frozen dataclasses for links, joints and their geometry.

Field names follow URDF (``origin``, ``axis``, ``limit``, ``mimic``) so a ROS user
recognises them. Lengths in metres, angles in radians, masses in kg.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np

JointType = Literal["revolute", "continuous", "prismatic", "fixed", "floating", "planar"]
GeometryKind = Literal["mesh", "box", "cylinder", "sphere"]


def rpy_matrix(rpy: tuple[float, float, float]) -> np.ndarray:
    """Rotation matrix of URDF roll-pitch-yaw (fixed axes x, then y, then z), shape (3, 3)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


#: how far from orthonormal (largest entry of R R^T - I) a matrix may be for the closed
#: forms (:func:`rpy_of`, quaternions); anything else goes to scipy, which takes the
#: nearest rotation
_ORTHONORMAL = 1e-9
#: [-] cos(pitch) below which roll and yaw are one angle (gimbal lock): yaw is then 0,
#: scipy's convention (above it the first column's direction still fixes yaw to rounding)
_LOCK_COS = 1e-12


def _dot(x: list[float], y: list[float]) -> float:
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


def rotation_rows(r: np.ndarray) -> list[list[float]] | None:
    """``r``'s rows as floats if it is a proper rotation matrix (3, 3), else None."""
    m = np.asarray(r, float)
    if m.shape != (3, 3):
        return None
    rows = m.tolist()  # nine floats: plain arithmetic beats numpy's per-call cost here
    u, v, w = rows
    grams = (_dot(u, u) - 1.0, _dot(v, v) - 1.0, _dot(w, w) - 1.0, _dot(u, v), _dot(u, w),
             _dot(v, w))
    if not all(abs(x) <= _ORTHONORMAL for x in grams):  # NaN fails too
        return None
    det = (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
           + u[2] * (v[0] * w[1] - v[1] * w[0]))
    return rows if det > 0.0 else None


def _scipy_rpy(r: np.ndarray) -> tuple[float, float, float]:
    from scipy.spatial.transform import Rotation  # only for a matrix that is no rotation

    with warnings.catch_warnings():  # at the lock scipy warns that it sets yaw to 0: known
        warnings.simplefilter("ignore", UserWarning)
        a = Rotation.from_matrix(np.asarray(r, float)).as_euler("xyz")
    return float(a[0]), float(a[1]), float(a[2])


def rpy_of(r: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw [rad] of a rotation matrix, shape (3, 3): the inverse of
    :func:`rpy_matrix`. At gimbal lock (pitch = +-pi/2) roll and yaw are one angle: yaw
    is 0 and roll takes it (scipy's convention); near it, yaw comes from the first
    column and roll and pitch are solved after it, so the three give ``r`` back to
    rounding. A matrix that is not a rotation: scipy's answer for the nearest one."""
    rows = rotation_rows(r)
    if rows is None:
        return _scipy_rpy(r)
    (a, b, c), (d, e, f), (g, _, _) = rows
    yaw = math.atan2(d, a) if math.hypot(a, d) > _LOCK_COS else 0.0
    cy, sy = math.cos(yaw), math.sin(yaw)
    # Rz(-yaw) r = Ry(pitch) Rx(roll): its first column gives pitch, its second row roll
    return (math.atan2(sy * c - cy * f, cy * e - sy * b), math.atan2(-g, cy * a + sy * d),
            yaw)


@dataclass(frozen=True)
class Origin:
    """A pose: translation ``xyz`` [m] and URDF roll-pitch-yaw ``rpy`` [rad]."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def matrix(self) -> np.ndarray:
        """Homogeneous transform, shape (4, 4)."""
        t = np.eye(4)
        t[:3, :3] = rpy_matrix(self.rpy)
        t[:3, 3] = self.xyz
        return t


@dataclass(frozen=True)
class Inertial:
    """Mass [kg] at ``origin`` with inertia about it [kg m^2]."""

    mass: float
    origin: Origin
    ixx: float
    ixy: float
    ixz: float
    iyy: float
    iyz: float
    izz: float

    def tensor(self) -> np.ndarray:
        """The symmetric inertia tensor in the inertial frame, shape (3, 3)."""
        return np.array([
            [self.ixx, self.ixy, self.ixz],
            [self.ixy, self.iyy, self.iyz],
            [self.ixz, self.iyz, self.izz],
        ])


@dataclass(frozen=True)
class Geometry:
    """One URDF geometry.

    Attributes:
        kind: mesh, box, cylinder or sphere.
        uri: the mesh ``filename`` as written in the URDF (mesh only).
        path: where ``uri`` resolved on this machine (mesh only; None if it did not).
        scale: per-axis mesh scale (mesh only).
        size: box edge lengths [m].
        radius: sphere or cylinder radius [m].
        length: cylinder length along its z axis [m].
    """

    kind: GeometryKind
    uri: str | None = None
    path: Path | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None


@dataclass(frozen=True)
class Shape:
    """A visual or collision element: a geometry placed at ``origin`` in its link."""

    origin: Origin
    geometry: Geometry
    name: str | None = None


@dataclass(frozen=True)
class Link:
    name: str
    inertial: Inertial | None = None
    visuals: tuple[Shape, ...] = ()
    collisions: tuple[Shape, ...] = ()


@dataclass(frozen=True)
class Limit:
    """Joint limits as the URDF gives them: position [rad or m], effort [N m or N],
    velocity [rad/s or m/s]. ``lower``/``upper`` are None for continuous joints."""

    lower: float | None
    upper: float | None
    effort: float
    velocity: float


@dataclass(frozen=True)
class Mimic:
    """This joint's value is ``multiplier * q[joint] + offset``."""

    joint: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Joint:
    name: str
    type: JointType
    parent: str
    child: str
    origin: Origin = Origin()
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    limit: Limit | None = None
    mimic: Mimic | None = None

    @property
    def movable(self) -> bool:
        return self.type not in ("fixed",)


#: Below this mass [kg] a link on a fixed joint with no geometry is a frame, not a body
#: (onshape-to-robot writes 1e-9 kg and a zero inertia for its dummy frames).
FRAME_MASS = 1e-6


@dataclass(frozen=True)
class Robot:
    """A parsed robot: its links and joints as the URDF declares them.

    ``links`` and ``joints`` keep the file's order. The tree checks live in
    :mod:`arduinobot.description.checks`; a :class:`Robot` returned by the loader has passed the
    structural ones (one root, a tree, no dangling names).

    Attributes:
        name: the robot's name.
        links: link name -> link.
        joints: joint name -> joint.
        urdf: the (expanded) URDF text.
        source: the file the model was read from, if any.
        package_dirs: the package index used to resolve its URIs, as name -> folder.
    """

    name: str
    links: dict[str, Link]
    joints: dict[str, Joint]
    urdf: str
    source: Path | None = None
    package_dirs: dict[str, Path] = field(default_factory=dict)

    @cached_property
    def root(self) -> str:
        """The one link that is no joint's child."""
        children = {j.child for j in self.joints.values()}
        roots = [name for name in self.links if name not in children]
        return roots[0]

    @cached_property
    def parent_joint(self) -> dict[str, Joint]:
        """Child link name -> the joint that carries it."""
        return {j.child: j for j in self.joints.values()}

    @cached_property
    def child_joints(self) -> dict[str, tuple[Joint, ...]]:
        """Link name -> the joints it is the parent of, in file order."""
        out: dict[str, list[Joint]] = {name: [] for name in self.links}
        for j in self.joints.values():
            out[j.parent].append(j)
        return {k: tuple(v) for k, v in out.items()}

    @cached_property
    def topological_joints(self) -> tuple[Joint, ...]:
        """Every joint, parents before children (depth first from the root)."""
        order: list[Joint] = []
        stack = [self.root]
        while stack:
            link = stack.pop()
            kids = self.child_joints[link]
            order.extend(kids)
            stack.extend(j.child for j in reversed(kids))
        return tuple(order)

    @cached_property
    def frame_links(self) -> tuple[str, ...]:
        """Links that are only frames: on a fixed joint, with no visual and no collision,
        and no inertial or a negligible mass (< :data:`FRAME_MASS` kg). ``tool0`` and
        onshape-to-robot's ``*_frame_link`` are such; a simulator merges them into their
        parent, and they name a tool point."""
        out = []
        for name, link in self.links.items():
            j = self.parent_joint.get(name)
            ine = link.inertial
            if j is None or j.movable or link.visuals or link.collisions:
                continue
            if ine is None or ine.mass < FRAME_MASS:
                out.append(name)
        return tuple(out)

    @cached_property
    def actuated_joints(self) -> tuple[str, ...]:
        """Movable joints that are not mimics, in tree order: the robot's DOF."""
        return tuple(j.name for j in self.topological_joints if j.movable and j.mimic is None)

    @cached_property
    def mimic_joints(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.topological_joints if j.mimic is not None)

    def mimics_of(self, joint: str) -> tuple[str, ...]:
        """The joints that follow ``joint``."""
        return tuple(j.name for j in self.joints.values() if j.mimic and j.mimic.joint == joint)

    def position_limits(self, joints: tuple[str, ...] | None = None) -> np.ndarray:
        """Lower and upper position limits, shape (n, 2); ±inf for continuous joints."""
        names = self.actuated_joints if joints is None else joints
        out = np.empty((len(names), 2))
        for i, name in enumerate(names):
            lim = self.joints[name].limit
            lo = lim.lower if lim is not None and lim.lower is not None else -np.inf
            hi = lim.upper if lim is not None and lim.upper is not None else np.inf
            out[i] = lo, hi
        return out

    def link_path(self, link: str) -> tuple[Joint, ...]:
        """The joints from the root down to ``link``."""
        chain: list[Joint] = []
        while link in self.parent_joint:
            j = self.parent_joint[link]
            chain.append(j)
            link = j.parent
        return tuple(reversed(chain))
