"""The robot model: frozen dataclasses for links, joints and their geometry.

Field names follow URDF (``origin``, ``axis``, ``limit``, ``mimic``) so a ROS user
recognises them. Lengths in metres, angles in radians, masses in kg.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np

from arduinobot.description.geometry import Geometry

# re-exported: a link's pose is a scene pose (defined once, in arduinobot.scene.pose)
from arduinobot.scene.pose import rotation_rows as rotation_rows
from arduinobot.scene.pose import rpy_matrix as rpy_matrix
from arduinobot.scene.pose import rpy_of as rpy_of

JointType = Literal["revolute", "continuous", "prismatic", "fixed", "floating", "planar"]


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
