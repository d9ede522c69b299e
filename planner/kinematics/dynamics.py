"""Rigid-body inverse dynamics (recursive Newton-Euler) from the URDF's inertials.

``tau = M(q) qdd + c(q, qd) + g(q)`` for the actuated joints, gravity -9.81 m/s^2 along
the root frame's z. The tree is flattened by :class:`~planner.kinematics.chain.Kinematics` (one
convention for joint order, mimics and held joints) and walked by numba kernels, since a
trajectory check evaluates every sample: a batch costs about 0.12 us per sample (five joints).

Mimic joints move with their leader (value, velocity and acceleration times the
multiplier) and their torque is folded into the leader's: ``tau_leader += multiplier *
tau_mimic`` (the leader's actuator drives both, as through a gear). Links without an
``<inertial>`` are massless. A carried payload (:meth:`InverseDynamics.with_payloads`)
is part of the link that holds it: its mass, centre of mass and inertia combined into
that link's (parallel axes), so the verifier and the effort-limited timing see it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from description.model import Robot, rpy_matrix

from ..errors import InvalidRequest
from ..path_limits import torque_coefficients
from .chain import FIXED, PRISMATIC, REVOLUTE, ChainArrays, Kinematics, rodrigues

# _rnea_batch's model arrays: the chain's (ChainArrays) then mass, com, inertia
_DynamicsArrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                        np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]

GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2] in the root frame


# states per block of the RNEA kernel (fewer in a smaller batch)
_LANES = 64


@numba.njit(cache=True, nogil=True)
def _rnea_batch(qs, qds, qdds, gravity, parent, origin, jtype, axis, src, scale, offset,
                mass, com, inertia, out):
    """Torques of many states into ``out`` (shape (m, dof)).

    Block by block of up to :data:`_LANES` states: every step of the recursion is a
    loop over the block's states, each value in a scratch row with one entry per state,
    and the loops kept small and without branches (the joint's sines and cosines in their
    own loop, its motion apart from the frame change, Newton-Euler apart from both) so the
    compiler vectorises most: 0.205 -> 0.12 us a state on the five-joint course arm,
    whose verification takes the torques of ~2.5k states a motion. Each state's arithmetic is
    the scalar recursion's, operation for operation (its torques bit for bit, whatever
    its block). ``w[link]`` rows: angular velocity (0:3), angular acceleration (3:6),
    origin linear acceleration (6:9), force (9:12), moment about the origin (12:15),
    the link's origin in its parent's frame (15:18); ``rot[k]`` joint k's rotation
    (row-major 3x3)."""
    nj = parent.shape[0]
    dof = out.shape[1]
    L = max(1, min(_LANES, qs.shape[0]))
    w = np.zeros((nj + 1, 18, L))
    rot = np.empty((nj, 9, L))
    tau = np.empty((dof, L))
    v = np.zeros(L)
    vd = np.zeros(L)
    vdd = np.zeros(L)
    for m0 in range(0, qs.shape[0], L):
        nb = min(L, qs.shape[0] - m0)
        for i in range(3):
            for b in range(L):
                w[0, i, b] = 0.0
                w[0, 3 + i, b] = 0.0
                w[0, 6 + i, b] = -gravity[i]  # a fixed base accelerating upwards: gravity
        tau[:, :] = 0.0
        for k in range(nj):
            c = k + 1
            p = parent[k]
            moves = jtype[k] != FIXED and src[k] >= 0
            jk = src[k]
            sk = scale[k]
            for b in range(L):  # lanes past the last state repeat it
                mb = m0 + min(b, nb - 1)
                v[b] = offset[k]
                vd[b] = 0.0
                vdd[b] = 0.0
                if moves:
                    v[b] += sk * qs[mb, jk]
                    vd[b] = sk * qds[mb, jk]
                    vdd[b] = sk * qdds[mb, jk]
            x, y, z = axis[k, 0], axis[k, 1], axis[k, 2]
            o = origin[k]
            # local transform child-in-parent: origin, then the joint motion
            if jtype[k] == REVOLUTE:
                for b in range(L):  # rodrigues is inlined (no 3x3 scratch a lane)
                    j00, j01, j02, j10, j11, j12, j20, j21, j22 = rodrigues(x, y, z, v[b])
                    for i in range(3):
                        a0, a1, a2 = o[i, 0], o[i, 1], o[i, 2]
                        rot[k, 3 * i, b] = a0 * j00 + a1 * j10 + a2 * j20
                        rot[k, 3 * i + 1, b] = a0 * j01 + a1 * j11 + a2 * j21
                        rot[k, 3 * i + 2, b] = a0 * j02 + a1 * j12 + a2 * j22
                    w[c, 15, b], w[c, 16, b], w[c, 17, b] = o[0, 3], o[1, 3], o[2, 3]
            else:
                for b in range(L):
                    for i in range(3):
                        for j in range(3):
                            rot[k, 3 * i + j, b] = o[i, j]
                    rx, ry, rz = o[0, 3], o[1, 3], o[2, 3]
                    if jtype[k] == PRISMATIC:
                        rx += v[b] * (o[0, 0] * x + o[0, 1] * y + o[0, 2] * z)
                        ry += v[b] * (o[1, 0] * x + o[1, 1] * y + o[1, 2] * z)
                        rz += v[b] * (o[2, 0] * x + o[2, 1] * y + o[2, 2] * z)
                    w[c, 15, b], w[c, 16, b], w[c, 17, b] = rx, ry, rz
            revolute = jtype[k] == REVOLUTE
            fixed = jtype[k] == FIXED
            mc = mass[c]
            mx, my, mz = com[c, 0], com[c, 1], com[c, 2]
            i00, i01, i02 = inertia[c, 0, 0], inertia[c, 0, 1], inertia[c, 0, 2]
            i10, i11, i12 = inertia[c, 1, 0], inertia[c, 1, 1], inertia[c, 1, 2]
            i20, i21, i22 = inertia[c, 2, 0], inertia[c, 2, 1], inertia[c, 2, 2]
            wp, wc, rk = w[p], w[c], rot[k]
            for b in range(L):
                rx, ry, rz = wc[15, b], wc[16, b], wc[17, b]
                # the parent's motion carried to the child origin, in the parent frame:
                # a_p + dw_p x r + w_p x (w_p x r)
                wx, wy, wz = wp[0, b], wp[1, b], wp[2, b]
                dx, dy, dz = wp[3, b], wp[4, b], wp[5, b]
                tx, ty, tz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
                ax = wp[6, b] + (dy * rz - dz * ry) + (wy * tz - wz * ty)
                ay = wp[7, b] + (dz * rx - dx * rz) + (wz * tx - wx * tz)
                az = wp[8, b] + (dx * ry - dy * rx) + (wx * ty - wy * tx)
                # rotated into the child frame (R^T)
                r00, r01, r02 = rk[0, b], rk[1, b], rk[2, b]
                r10, r11, r12 = rk[3, b], rk[4, b], rk[5, b]
                r20, r21, r22 = rk[6, b], rk[7, b], rk[8, b]
                cwx = r00 * wx + r10 * wy + r20 * wz
                cwy = r01 * wx + r11 * wy + r21 * wz
                cwz = r02 * wx + r12 * wy + r22 * wz
                cdx = r00 * dx + r10 * dy + r20 * dz
                cdy = r01 * dx + r11 * dy + r21 * dz
                cdz = r02 * dx + r12 * dy + r22 * dz
                cax = r00 * ax + r10 * ay + r20 * az
                cay = r01 * ax + r11 * ay + r21 * az
                caz = r02 * ax + r12 * ay + r22 * az
                wc[0, b], wc[1, b], wc[2, b] = cwx, cwy, cwz
                wc[3, b], wc[4, b], wc[5, b] = cdx, cdy, cdz
                wc[6, b], wc[7, b], wc[8, b] = cax, cay, caz
            # the joint's own motion; w x s with w still the parent's, in the child frame
            if revolute:
                for b in range(L):
                    cwx, cwy, cwz = wc[0, b], wc[1, b], wc[2, b]
                    tx, ty, tz = cwy * z - cwz * y, cwz * x - cwx * z, cwx * y - cwy * x
                    wc[3, b] += x * vdd[b] + tx * vd[b]
                    wc[4, b] += y * vdd[b] + ty * vd[b]
                    wc[5, b] += z * vdd[b] + tz * vd[b]
                    wc[0, b] = cwx + x * vd[b]
                    wc[1, b] = cwy + y * vd[b]
                    wc[2, b] = cwz + z * vd[b]
            elif not fixed:
                for b in range(L):
                    cwx, cwy, cwz = wc[0, b], wc[1, b], wc[2, b]
                    tx, ty, tz = cwy * z - cwz * y, cwz * x - cwx * z, cwx * y - cwy * x
                    wc[6, b] += x * vdd[b] + 2.0 * tx * vd[b]
                    wc[7, b] += y * vdd[b] + 2.0 * ty * vd[b]
                    wc[8, b] += z * vdd[b] + 2.0 * tz * vd[b]
            for b in range(L):
                cwx, cwy, cwz = wc[0, b], wc[1, b], wc[2, b]
                cdx, cdy, cdz = wc[3, b], wc[4, b], wc[5, b]
                cax, cay, caz = wc[6, b], wc[7, b], wc[8, b]
                # Newton-Euler at the centre of mass, moment about the link origin
                tx, ty, tz = cwy * mz - cwz * my, cwz * mx - cwx * mz, cwx * my - cwy * mx
                fx = mc * (cax + (cdy * mz - cdz * my) + (cwy * tz - cwz * ty))
                fy = mc * (cay + (cdz * mx - cdx * mz) + (cwz * tx - cwx * tz))
                fz = mc * (caz + (cdx * my - cdy * mx) + (cwx * ty - cwy * tx))
                wc[9, b], wc[10, b], wc[11, b] = fx, fy, fz
                iwx = i00 * cwx + i01 * cwy + i02 * cwz
                iwy = i10 * cwx + i11 * cwy + i12 * cwz
                iwz = i20 * cwx + i21 * cwy + i22 * cwz
                wc[12, b] = (i00 * cdx + i01 * cdy + i02 * cdz + (cwy * iwz - cwz * iwy)
                             + (my * fz - mz * fy))
                wc[13, b] = (i10 * cdx + i11 * cdy + i12 * cdz + (cwz * iwx - cwx * iwz)
                             + (mz * fx - mx * fz))
                wc[14, b] = (i20 * cdx + i21 * cdy + i22 * cdz + (cwx * iwy - cwy * iwx)
                             + (mx * fy - my * fx))
        for k in range(nj - 1, -1, -1):
            c = k + 1
            p = parent[k]
            wp, wc, rk = w[p], w[c], rot[k]
            ax0, ax1, ax2 = axis[k, 0], axis[k, 1], axis[k, 2]
            if jtype[k] != FIXED and src[k] >= 0:
                jk, sk = src[k], scale[k]
                if jtype[k] == REVOLUTE:
                    for b in range(L):
                        tau[jk, b] += sk * (ax0 * wc[12, b] + ax1 * wc[13, b] + ax2 * wc[14, b])
                else:
                    for b in range(L):
                        tau[jk, b] += sk * (ax0 * wc[9, b] + ax1 * wc[10, b] + ax2 * wc[11, b])
            if p == 0:
                continue  # the root is fixed: its wrench is the base reaction
            for b in range(L):  # the wrench into the parent frame (R)
                fx, fy, fz = wc[9, b], wc[10, b], wc[11, b]
                nx, ny, nz = wc[12, b], wc[13, b], wc[14, b]
                r00, r01, r02 = rk[0, b], rk[1, b], rk[2, b]
                r10, r11, r12 = rk[3, b], rk[4, b], rk[5, b]
                r20, r21, r22 = rk[6, b], rk[7, b], rk[8, b]
                gx = r00 * fx + r01 * fy + r02 * fz
                gy = r10 * fx + r11 * fy + r12 * fz
                gz = r20 * fx + r21 * fy + r22 * fz
                rx, ry, rz = wc[15, b], wc[16, b], wc[17, b]
                wp[9, b] += gx
                wp[10, b] += gy
                wp[11, b] += gz
                wp[12, b] += r00 * nx + r01 * ny + r02 * nz + (ry * gz - rz * gy)
                wp[13, b] += r10 * nx + r11 * ny + r12 * nz + (rz * gx - rx * gz)
                wp[14, b] += r20 * nx + r21 * ny + r22 * nz + (rx * gy - ry * gx)
        for b in range(nb):
            for i in range(dof):
                out[m0 + b, i] = tau[i, b]


def _lump_fixed(args: ChainArrays, mass: np.ndarray, com: np.ndarray,
                inertia: np.ndarray) -> _DynamicsArrays:
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


@dataclass(frozen=True)
class Payload:
    """A rigid mass a link carries.

    Attributes:
        link: the link that holds it.
        mass: [kg], >= 0.
        com: its centre of mass in the link's frame [m], shape (3,).
        inertia: its inertia about its centre of mass in the link's axes [kg m^2],
            shape (3, 3).
    """

    link: str
    mass: float
    com: tuple[float, float, float]
    inertia: tuple[tuple[float, float, float], ...]


def combine_inertia(m1: float, c1: np.ndarray, i1: np.ndarray, m2: float, c2: np.ndarray,
                    i2: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Two rigid bodies on one frame as one: total mass, centre of mass and inertia about
    it (parallel axes), all in that frame."""
    m = m1 + m2
    if m <= 0.0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    c = (m1 * np.asarray(c1, float) + m2 * np.asarray(c2, float)) / m
    out = np.zeros((3, 3))
    for mk, ck, ik in ((m1, c1, i1), (m2, c2, i2)):
        d = np.asarray(ck, float) - c
        out += np.asarray(ik, float) + mk * (d @ d * np.eye(3) - np.outer(d, d))
    return m, c, out


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
        self.payloads: tuple[Payload, ...] = ()

    def with_payloads(self, payloads: Sequence[Payload]) -> InverseDynamics:
        """This robot's dynamics with ``payloads`` added to the links that hold them
        (each combined into its link's mass, centre of mass and inertia before the fixed
        links are lumped). ``payloads`` () is this one."""
        if not payloads:
            return self
        out = InverseDynamics.__new__(InverseDynamics)
        out.kinematics, out.robot = self.kinematics, self.robot
        out.joint_names = self.joint_names
        out.gravity_acceleration = self.gravity_acceleration.copy()
        mass, com, inertia = self._mass.copy(), self._com.copy(), self._inertia.copy()
        index = self.kinematics.link_index
        for p in payloads:
            if p.link not in index:
                raise InvalidRequest(f"no link '{p.link}' in '{self.robot.name}'",
                                     field="attached.link")
            i = index[p.link]
            mass[i], com[i], inertia[i] = combine_inertia(
                mass[i], com[i], inertia[i], p.mass, np.asarray(p.com, float),
                np.asarray(p.inertia, float))
        out._mass, out._com, out._inertia = mass, com, inertia
        out._model = _lump_fixed(self.kinematics._args(), mass, com, inertia)
        out.payloads = tuple(self.payloads) + tuple(payloads)
        return out

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
        return torque_coefficients(self, np.asarray(p, float), np.asarray(ps, float),
                                   np.asarray(pss, float))
