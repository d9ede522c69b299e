"""Forward kinematics of every link, for one joint vector or a batch of them.

The tree is flattened once into arrays (joint origins, axes, parent indices, mimic
maps) and walked by a numba-compiled kernel: a planner calls FK for every state it
checks, and numpy's per-call overhead on 4x4 matrices alone would cost ~20x more.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.model import Robot

# joint type codes of the kernels (shared with arduinobot.planner.kinematics.dynamics)
FIXED, REVOLUTE, PRISMATIC = 0, 1, 2


class Chain(NamedTuple):
    """The flattened tree as the numba kernels take it (one argument, not seven).

    Joint ``k`` carries link ``k + 1``; its value is ``scale[k] * q[src[k]] + offset[k]``
    (``src`` -1: held at ``offset``).

    Attributes:
        parent: each joint's parent link index, shape (n_joints,) int64.
        origin: each joint's origin, shape (n_joints, 4, 4).
        jtype: FIXED, REVOLUTE or PRISMATIC, shape (n_joints,) int64.
        axis: unit axes in the joint frame, shape (n_joints, 3).
        src: the actuated joint each follows, or -1, shape (n_joints,) int64.
        scale, offset: shape (n_joints,).
    """

    parent: np.ndarray
    origin: np.ndarray
    jtype: np.ndarray
    axis: np.ndarray
    src: np.ndarray
    scale: np.ndarray
    offset: np.ndarray


@numba.njit(cache=True, nogil=True, inline="always")
def rodrigues(x: float, y: float, z: float, v: float
              ) -> tuple[float, float, float, float, float, float, float, float, float]:
    """The rotation by ``v`` [rad] about the unit axis (x, y, z), row-major (9 floats).
    Inlined into its callers by numba (the inverse dynamics kernel's lanes: a call per
    state made it ~40% slower)."""
    c_, s_ = np.cos(v), np.sin(v)
    t_ = 1.0 - c_
    return (t_ * x * x + c_, t_ * x * y - s_ * z, t_ * x * z + s_ * y,
            t_ * x * y + s_ * z, t_ * y * y + c_, t_ * y * z - s_ * x,
            t_ * x * z - s_ * y, t_ * y * z + s_ * x, t_ * z * z + c_)


@numba.njit(cache=True, nogil=True)
def joint_rotation(origin: np.ndarray, x: float, y: float, z: float, v: float,
                   out: np.ndarray) -> None:
    """``out[:3, :3] = origin[:3, :3] @ R``, R the rotation by ``v`` [rad] about the unit
    axis (x, y, z) (:func:`rodrigues`)."""
    j00, j01, j02, j10, j11, j12, j20, j21, j22 = rodrigues(x, y, z, v)
    for i in range(3):
        a0, a1, a2 = origin[i, 0], origin[i, 1], origin[i, 2]
        out[i, 0] = a0 * j00 + a1 * j10 + a2 * j20
        out[i, 1] = a0 * j01 + a1 * j11 + a2 * j21
        out[i, 2] = a0 * j02 + a1 * j12 + a2 * j22


# What the kernels take after the joint values, in this order: parent, origin, jtype,
# axis, src, scale, offset (Kinematics._args). A fixed-length tuple, so the kernels'
# typed signatures check a call that spreads it.
ChainArrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                    np.ndarray]


@numba.njit(cache=True, nogil=True)
def _fk_into(q: np.ndarray, parent: np.ndarray, origin: np.ndarray, jtype: np.ndarray,
             axis: np.ndarray, src: np.ndarray, scale: np.ndarray, offset: np.ndarray,
             out: np.ndarray) -> None:
    # out[0] is the root (identity); joint k carries link k + 1.
    for r in range(4):
        for c in range(4):
            out[0, r, c] = 1.0 if r == c else 0.0
    local = np.empty((4, 4))
    for k in range(parent.shape[0]):
        for r in range(4):
            for c in range(4):
                local[r, c] = origin[k, r, c]
        if jtype[k] != FIXED:
            v = offset[k] + (scale[k] * q[src[k]] if src[k] >= 0 else 0.0)
            x, y, z = axis[k, 0], axis[k, 1], axis[k, 2]
            if jtype[k] == REVOLUTE:
                joint_rotation(origin[k], x, y, z, v, local)
            else:
                for r in range(3):
                    local[r, 3] += v * (origin[k, r, 0] * x + origin[k, r, 1] * y
                                        + origin[k, r, 2] * z)
        p = parent[k]
        for r in range(3):
            for c in range(4):
                acc = out[p, r, 3] if c == 3 else 0.0
                for i in range(3):
                    acc += out[p, r, i] * local[i, c]
                out[k + 1, r, c] = acc
        out[k + 1, 3, 0] = 0.0
        out[k + 1, 3, 1] = 0.0
        out[k + 1, 3, 2] = 0.0
        out[k + 1, 3, 3] = 1.0


@numba.njit(cache=True, nogil=True)
def _fk_batch_into(qs: np.ndarray, parent: np.ndarray, origin: np.ndarray, jtype: np.ndarray,
                   axis: np.ndarray, src: np.ndarray, scale: np.ndarray, offset: np.ndarray,
                   out: np.ndarray) -> None:
    for m in range(qs.shape[0]):
        _fk_into(qs[m], parent, origin, jtype, axis, src, scale, offset, out[m])


class Kinematics:
    """Forward kinematics of a :class:`~arduinobot.description.model.Robot`.

    Joint vectors are ordered as ``joint_names`` (the actuated joints by default); mimic
    joints follow their leaders. Poses are homogeneous transforms in the root frame.

    Args:
        robot: the model.
        joint_names: the order of the joint vector; defaults to ``robot.actuated_joints``.
    """

    def __init__(self, robot: Robot, joint_names: Sequence[str] | None = None) -> None:
        self.robot = robot
        self.joint_names: tuple[str, ...] = tuple(joint_names or robot.actuated_joints)
        index = {n: i for i, n in enumerate(self.joint_names)}
        for n in self.joint_names:
            j = robot.joints.get(n)
            if j is None or not j.movable or j.mimic is not None:
                raise InvalidRequest(f"'{n}' is not an actuated joint of '{robot.name}'",
                                     field="joint_names")
        self.link_names: tuple[str, ...] = (robot.root,) + tuple(
            j.child for j in robot.topological_joints)
        self.link_index = {n: i for i, n in enumerate(self.link_names)}
        joints = robot.topological_joints
        self._parent = np.array([self.link_index[j.parent] for j in joints], dtype=np.int64)
        self._origin = np.array([j.origin.matrix() for j in joints])
        self._axis = np.ascontiguousarray(
            [np.asarray(j.axis, float) / (np.linalg.norm(j.axis) or 1.0) for j in joints])
        # Each joint's value is scale * q[source] + offset; source -1 means fixed at offset.
        drive = []  # (source, scale, offset) per joint
        for j in joints:
            if j.mimic is not None:
                drive.append((index.get(j.mimic.joint, -1), j.mimic.multiplier, j.mimic.offset))
            elif j.movable and j.name in index:
                drive.append((index[j.name], 1.0, 0.0))
            else:  # a fixed joint, or an actuated joint left out of joint_names (held at 0)
                drive.append((-1, 0.0, 0.0))
        self._src = np.array([d[0] for d in drive], dtype=np.int64)
        self._scale = np.array([d[1] for d in drive], dtype=float)
        self._offset = np.array([d[2] for d in drive], dtype=float)
        codes = {"fixed": FIXED, "prismatic": PRISMATIC}
        self._jtype = np.array([codes.get(j.type, REVOLUTE) if d[0] >= 0 or j.type == "fixed"
                                else FIXED for j, d in zip(joints, drive)], dtype=np.int64)
        #: the same arrays bundled for the numba kernels (collision's among them)
        self.chain = Chain(*self._args())

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    def _args(self) -> ChainArrays:
        return (self._parent, self._origin, self._jtype, self._axis, self._src,
                self._scale, self._offset)

    def link_poses(self, q: ArrayLike, out: np.ndarray | None = None) -> np.ndarray:
        """Every link's pose for one state, shape (n_links, 4, 4), in ``link_names`` order.

        Pass ``out`` (shape (n_links, 4, 4), float64) to reuse a buffer on a hot path.
        """
        q = np.ascontiguousarray(q, dtype=float)
        if q.shape != (self.dof,):
            raise InvalidRequest(f"expected {self.dof} joint values ({', '.join(self.joint_names)})"
                                 f", got shape {q.shape}", field="q")
        if out is None:
            out = np.empty((len(self.link_names), 4, 4))
        _fk_into(q, *self._args(), out)
        return out

    def link_poses_batch(self, qs: ArrayLike) -> np.ndarray:
        """Every link's pose for many states: ``qs`` shape (m, dof) -> (m, n_links, 4, 4)."""
        qs = np.ascontiguousarray(qs, dtype=float)
        if qs.ndim != 2 or qs.shape[1] != self.dof:
            raise InvalidRequest(f"expected shape (m, {self.dof}), got {qs.shape}", field="q")
        out = np.empty((qs.shape[0], len(self.link_names), 4, 4))
        _fk_batch_into(qs, *self._args(), out)
        return out

    def link_pose(self, q: ArrayLike, link: str) -> np.ndarray:
        """One link's pose, shape (4, 4)."""
        try:
            i = self.link_index[link]
        except KeyError:
            raise InvalidRequest(f"no link '{link}' in '{self.robot.name}'", field="link") from None
        return self.link_poses(q)[i]

    def point_position(self, q: ArrayLike, link: str, offset: ArrayLike) -> np.ndarray:
        """Position [m] of a point fixed at ``offset`` in ``link``'s frame, shape (3,)."""
        t = self.link_pose(q, link)
        return t[:3, :3] @ np.asarray(offset, float) + t[:3, 3]
