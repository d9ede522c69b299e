"""Forward kinematics of every link, for one joint vector or a batch of them.

The tree is flattened once into arrays (joint origins, axes, parent indices, mimic
maps) and walked by a numba-compiled kernel: a planner calls FK for every state it
checks, and numpy's per-call overhead on 4x4 matrices alone would cost ~20x more.
"""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np
from numpy.typing import ArrayLike

from description.model import Robot

from .errors import InvalidRequest

_FIXED, _REVOLUTE, _PRISMATIC = 0, 1, 2


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
        if jtype[k] != _FIXED:
            v = offset[k] + (scale[k] * q[src[k]] if src[k] >= 0 else 0.0)
            x, y, z = axis[k, 0], axis[k, 1], axis[k, 2]
            if jtype[k] == _REVOLUTE:
                c_, s_ = np.cos(v), np.sin(v)
                t_ = 1.0 - c_
                rot = np.empty((3, 3))
                rot[0, 0] = t_ * x * x + c_
                rot[0, 1] = t_ * x * y - s_ * z
                rot[0, 2] = t_ * x * z + s_ * y
                rot[1, 0] = t_ * x * y + s_ * z
                rot[1, 1] = t_ * y * y + c_
                rot[1, 2] = t_ * y * z - s_ * x
                rot[2, 0] = t_ * x * z - s_ * y
                rot[2, 1] = t_ * y * z + s_ * x
                rot[2, 2] = t_ * z * z + c_
                for r in range(3):
                    a0, a1, a2 = origin[k, r, 0], origin[k, r, 1], origin[k, r, 2]
                    for c in range(3):
                        local[r, c] = a0 * rot[0, c] + a1 * rot[1, c] + a2 * rot[2, c]
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
    """Forward kinematics of a :class:`~description.model.Robot`.

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
        self._type = [j.type for j in joints]
        self._axis = [np.asarray(j.axis, float) / (np.linalg.norm(j.axis) or 1.0) for j in joints]
        # Each joint's value is scale * q[source] + offset; source -1 means fixed at offset.
        src, scale, offset = [], [], []
        for j in joints:
            if j.mimic is not None:
                leader = index.get(j.mimic.joint, -1)
                src.append(leader)
                scale.append(j.mimic.multiplier)
                offset.append(j.mimic.offset)
            elif j.movable and j.name in index:
                src.append(index[j.name])
                scale.append(1.0)
                offset.append(0.0)
            else:
                # a fixed joint, or an actuated joint left out of joint_names (held at 0)
                src.append(-1)
                scale.append(0.0)
                offset.append(0.0)
        self._src = np.array(src, dtype=np.int64)
        self._scale = np.array(scale)
        self._offset = np.array(offset)
        codes = {"fixed": _FIXED, "prismatic": _PRISMATIC}
        self._jtype = np.array([codes.get(t, _REVOLUTE) if s >= 0 or t == "fixed" else _FIXED
                                for t, s in zip(self._type, src)], dtype=np.int64)
        self._axis_arr = np.ascontiguousarray(self._axis)

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    def joint_values(self, q: ArrayLike) -> np.ndarray:
        """Every tree joint's value (mimics applied), in topological order, shape (..., nj)."""
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != self.dof:
            raise InvalidRequest(f"expected {self.dof} joint values ({', '.join(self.joint_names)})"
                                 f", got {q.shape[-1]}", field="q")
        safe = np.where(self._src >= 0, self._src, 0)
        return np.where(self._src >= 0, q[..., safe] * self._scale, 0.0) + self._offset

    def _args(self) -> tuple[np.ndarray, ...]:
        return (self._parent, self._origin, self._jtype, self._axis_arr, self._src,
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
