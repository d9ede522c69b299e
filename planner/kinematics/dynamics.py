"""Rigid-body inverse dynamics (recursive Newton-Euler) from the URDF's inertials.

``tau = M(q) qdd + c(q, qd) + g(q)`` for the actuated joints, gravity -9.81 m/s^2 along
the root frame's z. The tree is flattened by :class:`~planner.kinematics.chain.Kinematics` (one
convention for joint order, mimics and held joints) and walked by numba kernels, since a
trajectory check evaluates every sample: a batch costs about a microsecond per sample.

Mimic joints move with their leader (value, velocity and acceleration times the
multiplier) and their torque is folded into the leader's: ``tau_leader += multiplier *
tau_mimic`` (the leader's actuator drives both, as through a gear). Links without an
``<inertial>`` are massless.
"""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np
from numpy.typing import ArrayLike

from description.model import Robot, rpy_matrix

from ..errors import InvalidRequest
from ..path_limits import torque_coefficients
from .chain import FIXED, PRISMATIC, REVOLUTE, Kinematics, joint_rotation

GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2] in the root frame


@numba.njit(cache=True, nogil=True)
def _cross(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True, nogil=True)
def _rnea_into(q, qd, qdd, gravity, parent, origin, jtype, axis, src, scale, offset,
               mass, com, inertia, work, tau):
    """One state. ``work`` is scratch, shape (n_links, 7, 3): rows are angular velocity,
    angular acceleration, origin linear acceleration, force, moment, child-in-parent
    translation, and a temporary."""
    nj = parent.shape[0]
    rot = np.empty((nj, 3, 3))
    tmp = np.empty(3)
    tmp2 = np.empty(3)
    for i in range(3):
        work[0, 0, i] = 0.0
        work[0, 1, i] = 0.0
        work[0, 2, i] = -gravity[i]  # a fixed base accelerating upwards stands in for gravity
    for i in range(tau.shape[0]):
        tau[i] = 0.0
    for k in range(nj):
        c = k + 1
        p = parent[k]
        v = offset[k]
        vd = 0.0
        vdd = 0.0
        if jtype[k] != FIXED and src[k] >= 0:
            v += scale[k] * q[src[k]]
            vd = scale[k] * qd[src[k]]
            vdd = scale[k] * qdd[src[k]]
        x, y, z = axis[k, 0], axis[k, 1], axis[k, 2]
        # local transform child-in-parent: origin, then the joint motion
        r = work[c, 5]
        for i in range(3):
            r[i] = origin[k, i, 3]
        if jtype[k] == REVOLUTE:
            joint_rotation(origin[k], x, y, z, v, rot[k])
        else:
            for i in range(3):
                for j in range(3):
                    rot[k, i, j] = origin[k, i, j]
            if jtype[k] == PRISMATIC:
                for i in range(3):
                    r[i] += v * (origin[k, i, 0] * x + origin[k, i, 1] * y + origin[k, i, 2] * z)
        wp, dwp, ap = work[p, 0], work[p, 1], work[p, 2]
        w, dw, a = work[c, 0], work[c, 1], work[c, 2]
        # parent terms at the child origin, in the parent frame
        _cross(wp, r, tmp)
        _cross(wp, tmp, tmp2)
        _cross(dwp, r, tmp)
        for i in range(3):
            tmp[i] += ap[i] + tmp2[i]
        for i in range(3):  # rotate into the child frame (R^T)
            w[i] = rot[k, 0, i] * wp[0] + rot[k, 1, i] * wp[1] + rot[k, 2, i] * wp[2]
            dw[i] = rot[k, 0, i] * dwp[0] + rot[k, 1, i] * dwp[1] + rot[k, 2, i] * dwp[2]
            a[i] = rot[k, 0, i] * tmp[0] + rot[k, 1, i] * tmp[1] + rot[k, 2, i] * tmp[2]
        s = axis[k]
        if jtype[k] == REVOLUTE:
            _cross(w, s, tmp)  # w here is still the parent's, in the child frame
            for i in range(3):
                dw[i] += s[i] * vdd + tmp[i] * vd
                w[i] += s[i] * vd
        elif jtype[k] == PRISMATIC:
            _cross(w, s, tmp)
            for i in range(3):
                a[i] += s[i] * vdd + 2.0 * tmp[i] * vd
        # Newton-Euler at the centre of mass, moment about the link origin
        m = mass[c]
        cm = com[c]
        _cross(w, cm, tmp)
        _cross(w, tmp, tmp2)
        _cross(dw, cm, tmp)
        f = work[c, 3]
        for i in range(3):
            f[i] = m * (a[i] + tmp[i] + tmp2[i])
        iw = work[c, 6]
        for i in range(3):
            iw[i] = inertia[c, i, 0] * w[0] + inertia[c, i, 1] * w[1] + inertia[c, i, 2] * w[2]
        _cross(w, iw, tmp)
        _cross(cm, f, tmp2)
        n = work[c, 4]
        for i in range(3):
            n[i] = (inertia[c, i, 0] * dw[0] + inertia[c, i, 1] * dw[1]
                    + inertia[c, i, 2] * dw[2] + tmp[i] + tmp2[i])
    for k in range(nj - 1, -1, -1):
        c = k + 1
        p = parent[k]
        f, n, r = work[c, 3], work[c, 4], work[c, 5]
        if jtype[k] != FIXED and src[k] >= 0:
            s = axis[k]
            t = s[0] * n[0] + s[1] * n[1] + s[2] * n[2] if jtype[k] == REVOLUTE \
                else s[0] * f[0] + s[1] * f[1] + s[2] * f[2]
            tau[src[k]] += scale[k] * t
        if p == 0:
            continue  # the root is fixed: its wrench is the base reaction
        for i in range(3):
            tmp[i] = rot[k, i, 0] * f[0] + rot[k, i, 1] * f[1] + rot[k, i, 2] * f[2]
            tmp2[i] = rot[k, i, 0] * n[0] + rot[k, i, 1] * n[1] + rot[k, i, 2] * n[2]
        fp, np_ = work[p, 3], work[p, 4]
        for i in range(3):
            fp[i] += tmp[i]
            np_[i] += tmp2[i]
        _cross(r, tmp, tmp2)
        for i in range(3):
            np_[i] += tmp2[i]


@numba.njit(cache=True, nogil=True)
def _rnea_batch(qs, qds, qdds, gravity, parent, origin, jtype, axis, src, scale, offset,
                mass, com, inertia, out):
    work = np.empty((parent.shape[0] + 1, 7, 3))
    for m in range(qs.shape[0]):
        _rnea_into(qs[m], qds[m], qdds[m], gravity, parent, origin, jtype, axis, src, scale,
                   offset, mass, com, inertia, work, out[m])


def _lump_fixed(args: tuple[np.ndarray, ...], mass: np.ndarray, com: np.ndarray,
                inertia: np.ndarray) -> tuple[np.ndarray, ...]:
    """The RNEA's arrays with every link on a fixed joint merged into the link it hangs
    from (its mass, centre of mass and inertia combined there, parallel axes): the same
    torques for fewer links (a CAD export's camera mounts, flanges and tool frames).

    ``args`` are :meth:`Kinematics._args`' arrays; link ``k + 1`` hangs from joint ``k``.
    """
    parent, origin, jtype, axis, src, scale, offset = args
    host = [0]  # per link: the reduced link it is merged into
    place = [np.eye(4)]  # per link: its pose in that reduced link's frame
    keep: list[int] = []  # the joints the reduced model keeps
    for k in range(len(parent)):
        p = parent[k]
        if jtype[k] == FIXED:
            host.append(host[p])
            place.append(place[p] @ origin[k])
        else:
            keep.append(k)
            host.append(len(keep))
            place.append(np.eye(4))
    n = len(keep) + 1
    m, c, inertia_c = np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3, 3))
    for link in range(len(host)):  # first moments, then inertia about each new COM
        h, t = host[link], place[link]
        m[h] += mass[link]
        c[h] += mass[link] * (t[:3, :3] @ com[link] + t[:3, 3])
    c /= np.where(m > 0, m, 1.0)[:, None]
    for link in range(len(host)):
        h, t = host[link], place[link]
        r = t[:3, :3]
        d = r @ com[link] + t[:3, 3] - c[h]
        inertia_c[h] += r @ inertia[link] @ r.T + mass[link] * (d @ d * np.eye(3)
                                                                 - np.outer(d, d))
    org = np.array([place[parent[k]] @ origin[k] for k in keep]).reshape(-1, 4, 4)
    par = np.array([host[parent[k]] for k in keep], dtype=parent.dtype)
    idx = np.array(keep, dtype=np.int64)
    return (par, org, jtype[idx], axis[idx], src[idx], scale[idx], offset[idx], m, c,
            inertia_c)


class InverseDynamics:
    """Joint torques of a :class:`~description.model.Robot` from its URDF inertials.

    Args:
        robot: the model.
        joint_names: the joint vector's order; defaults to ``robot.actuated_joints``
            (actuated joints left out are held at 0, as in :class:`Kinematics`).

    Attributes:
        joint_names: the joints torques are given for.
        gravity_acceleration: [m/s^2] in the root frame, shape (3,).
    """

    def __init__(self, robot: Robot, joint_names: Sequence[str] | None = None) -> None:
        self.kinematics = Kinematics(robot, joint_names)
        self.robot = robot
        self.joint_names = self.kinematics.joint_names
        self.gravity_acceleration = GRAVITY.copy()
        links = self.kinematics.link_names
        self._mass = np.zeros(len(links))
        self._com = np.zeros((len(links), 3))
        self._inertia = np.zeros((len(links), 3, 3))
        for i, name in enumerate(links):
            inertial = robot.links[name].inertial
            if inertial is None:
                continue
            rot = rpy_matrix(inertial.origin.rpy)
            self._mass[i] = inertial.mass
            self._com[i] = inertial.origin.xyz
            self._inertia[i] = rot @ inertial.tensor() @ rot.T  # about the COM, link axes
        self._model = _lump_fixed(self.kinematics._args(), self._mass, self._com,
                                  self._inertia)

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    def _batch(self, qs: ArrayLike, qds: ArrayLike, qdds: ArrayLike, gravity: np.ndarray,
               field: str = "q") -> np.ndarray:
        arrs = []
        for name, x in (("q", qs), ("qd", qds), ("qdd", qdds)):
            a = np.ascontiguousarray(x, dtype=float)
            if a.ndim != 2 or a.shape[1] != self.dof:
                raise InvalidRequest(f"expected shape (m, {self.dof}) "
                                     f"({', '.join(self.joint_names)}), got {a.shape}",
                                     field=name)
            if not np.all(np.isfinite(a)):
                raise InvalidRequest("must be finite", field=name)
            arrs.append(a)
        if not arrs[0].shape == arrs[1].shape == arrs[2].shape:
            raise InvalidRequest(f"q, qd and qdd differ in shape: {[a.shape for a in arrs]}",
                                 field=field)
        out = np.empty_like(arrs[0])
        _rnea_batch(arrs[0], arrs[1], arrs[2], gravity, *self._model, out)
        return out

    def torques(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> np.ndarray:
        """Joint torques [N m] (forces [N] for prismatic joints), shape (dof,).

        Args:
            q: positions [rad or m], qd: velocities [/s], qdd: accelerations [/s^2];
                each shape (dof,).

        Usable as toppra's ``JointTorqueConstraint(inv_dyn=...)`` callable.
        """
        return self._batch(np.reshape(q, (1, -1)), np.reshape(qd, (1, -1)),
                           np.reshape(qdd, (1, -1)), self.gravity_acceleration)[0]

    def torques_batch(self, qs: ArrayLike, qds: ArrayLike, qdds: ArrayLike) -> np.ndarray:
        """Torques of many states: each argument shape (m, dof) -> shape (m, dof)."""
        return self._batch(qs, qds, qdds, self.gravity_acceleration)

    def gravity(self, q: ArrayLike) -> np.ndarray:
        """``g(q)`` [N m]: the torques holding the arm still, shape (dof,)."""
        z = np.zeros((1, self.dof))
        return self._batch(np.reshape(q, (1, -1)), z, z, self.gravity_acceleration)[0]

    def velocity_product(self, q: ArrayLike, qd: ArrayLike) -> np.ndarray:
        """``c(q, qd)`` [N m]: Coriolis and centrifugal torques, shape (dof,)."""
        z = np.zeros((1, self.dof))
        return self._batch(np.reshape(q, (1, -1)), np.reshape(qd, (1, -1)), z,
                           np.zeros(3))[0]

    def mass_matrix(self, q: ArrayLike) -> np.ndarray:
        """``M(q)`` [kg m^2], symmetric positive definite, shape (dof, dof)."""
        return self.mass_matrix_batch(np.reshape(q, (1, -1)))[0]

    def mass_matrix_batch(self, qs: ArrayLike) -> np.ndarray:
        """``M(q)`` for many states: ``qs`` shape (m, dof) -> shape (m, dof, dof).

        Column j is the torque of a unit acceleration of joint j without gravity or
        velocity (dof RNEA passes per state).
        """
        qs = np.asarray(qs, dtype=float)
        if qs.ndim != 2 or qs.shape[1] != self.dof:
            raise InvalidRequest(f"expected shape (m, {self.dof}), got {qs.shape}", field="q")
        m, n = qs.shape
        rep = np.repeat(qs, n, axis=0)
        acc = np.tile(np.eye(n), (m, 1))
        cols = self._batch(rep, np.zeros_like(rep), acc, np.zeros(3))
        mm = cols.reshape(m, n, n).transpose(0, 2, 1)
        return 0.5 * (mm + mm.transpose(0, 2, 1))  # symmetric up to rounding; make it exact

    def path_coefficients(self, p: ArrayLike, ps: ArrayLike, pss: ArrayLike
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """toppra's second-order form ``tau = a(s) sdd + b(s) sd^2 + c(s)`` along a path.

        Args:
            p, ps, pss: the path q(s) and its first and second derivatives at the
                gridpoints, each shape (N, dof).

        Returns:
            ``a``, ``b``, ``c``, each shape (N, dof), in one batched call (what toppra's
            ``JointTorqueConstraint`` computes with 3N single calls).
        """
        return torque_coefficients(self, np.asarray(p, float), ps, pss)
