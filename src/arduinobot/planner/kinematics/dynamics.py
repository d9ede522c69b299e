"""Rigid-body inverse dynamics (recursive Newton-Euler) from the URDF's inertials.

``tau = M(q) qdd + c(q, qd) + g(q)`` for the actuated joints, gravity -9.81 m/s^2 along
the root frame's z. The tree is flattened by :class:`~arduinobot.planner.kinematics.chain.Kinematics` (one
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

import numpy as np
from numpy.typing import ArrayLike

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.model import Robot, rpy_matrix
from arduinobot.planner.kinematics.chain import FIXED, ChainArrays, Kinematics
from arduinobot.planner.kinematics.rnea import rnea_batch
from arduinobot.planner.path_limits import torque_coefficients
from arduinobot.scene.payload import Payload

# rnea_batch's model arrays: the chain's (ChainArrays) then mass, com, inertia
_DynamicsArrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                        np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]

GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2] in the root frame


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
    """Joint torques of a :class:`~arduinobot.description.model.Robot` from its URDF inertials.

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
        rnea_batch(arrs[0], arrs[1], arrs[2], gravity, *self._model, out)
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
