"""The tool frame's pose and Jacobian, pose IK, and following a target step by step.

The tool frame is the tcp point with its parent link's axes (``tcp.yaml`` gives a point,
no rotation). Orientation errors are rotation vectors in the goal's frame
(:func:`arduinobot.planner.kinematics.rotations.rotation_error`), so a per-axis tolerance bounds one
component and a free axis drops one row of the task Jacobian.

- :func:`tool_jacobian`: positions, rotations and the linear and angular Jacobians of the
  solved-for joints, for a batch of states (one batched FK call).
- :func:`pose_ik`: seeded multi-start damped least squares on position and the
  constrained orientation axes, for groups that can choose their orientation.
- :func:`track_step`: one local solve from a nearby state (a straight-line move follows
  its line with it, so the joints never jump to another branch).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from arduinobot.description.tcp import Tcp
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.ik import IkSolution
from arduinobot.planner.kinematics.ik_numeric import Chain, dedupe, wrap_into_limits
from arduinobot.planner.kinematics.rotations import rotation_error

__all__ = ["tool_jacobian", "pose_ik", "track_step", "axis_rows"]


def tool_jacobian(kin: Kinematics, tcp: Tcp, chain: Chain, qs: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For full joint vectors ``qs`` (m, dof): the tcp positions (m, 3) [m], the tool
    rotations (m, 3, 3), and the Jacobians of the chain's joints, linear (m, 3, n) and
    angular (m, 3, n), in the root frame."""
    qs = np.ascontiguousarray(np.atleast_2d(qs), float)
    poses = kin.link_poses_batch(qs)
    t = poses[:, chain.tcp_link]
    p = t[:, :3, :3] @ np.asarray(tcp.xyz, float) + t[:, :3, 3]
    rot = t[:, :3, :3] @ tcp.rotation()  # the tool frame (tcp.yaml's rpy)
    n = len(chain.joint_names)
    jp = np.zeros((len(qs), 3, n))
    jw = np.zeros((len(qs), 3, n))
    for c, link, axis, mult, rev in chain.terms:
        w = poses[:, link, :3, :3] @ axis
        if rev:
            jp[:, :, c] += mult * np.cross(w, p - poses[:, link, :3, 3])
            jw[:, :, c] += mult * w
        else:
            jp[:, :, c] += mult * w
    return p, rot, jp, jw


def axis_rows(free_axes: Sequence[str]) -> np.ndarray:
    """The indices (of x, y, z) of the constrained axes, shape (k,)."""
    return np.array([i for i, a in enumerate("xyz") if a not in free_axes], dtype=np.int64)


def _axis_error(rot: np.ndarray, goal: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The world-frame rotation (m, 3) [rad, to first order] turning the tool towards the
    goal on the constrained axes: ``0.5 sum_i r_i x g_i`` for all three, ``r_a x g_a``
    for the one axis a left constrained in direction (the other free), so the free
    rotation stays free; smooth everywhere, unlike a rotation vector near pi. Two free
    axes: the rotation-vector component of the one bounded, in the world frame."""
    r_cols, g_cols = np.swapaxes(rot, -1, -2), goal.T  # rows: the frames' axes
    if len(rows) == 3:
        return 0.5 * np.cross(r_cols, g_cols[None]).sum(axis=1)
    if len(rows) == 2:
        a = ({0, 1, 2} - set(rows.tolist())).pop()  # the free axis keeps its direction
        return np.cross(r_cols[:, a], g_cols[a][None])
    e = rotation_error(goal, rot)
    keep = np.zeros_like(e)
    keep[:, rows] = e[:, rows]
    return -(goal @ keep[:, :, None])[:, :, 0]


def _step(jac: np.ndarray, e: np.ndarray, err: np.ndarray) -> np.ndarray:
    # damped least squares, damping vanishing at a solution (as ik_numeric's)
    lam2 = np.clip(err, 1e-6, 0.1)[:, None, None] ** 2
    jt = jac.transpose(0, 2, 1)
    n = jac.shape[2]
    return np.linalg.solve(jt @ jac + lam2 * np.eye(n), jt @ e[:, :, None])[:, :, 0]


def _solve(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray, starts: np.ndarray,
           target_p: np.ndarray, target_r: np.ndarray | None, rows: np.ndarray,
           lower: np.ndarray, upper: np.ndarray, *, iterations: int, max_step: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """DLS from every start: (values (m, n), position error (m,) [m], orientation error
    (m, 3) [rad], rotation vector in the goal frame)."""
    qs = np.array(starts, float)
    full = np.tile(q_base, (len(qs), 1))
    lo = np.where(np.isfinite(lower), lower, -np.inf)
    hi = np.where(np.isfinite(upper), upper, np.inf)
    ep = np.full(len(qs), np.inf)
    eo = np.zeros((len(qs), 3))
    for _ in range(iterations + 1):
        full[:, chain.columns] = qs
        p, rot, jp, jw = tool_jacobian(kin, tcp, chain, full)
        e_lin = target_p - p
        ep = np.linalg.norm(e_lin, axis=1)
        if target_r is None or len(rows) == 0:
            jac, e = jp, e_lin
            size = ep
        else:
            jac = np.concatenate([jp, jw], axis=1)
            e = np.concatenate([e_lin, _axis_error(rot, target_r, rows)], axis=1)
            size = np.linalg.norm(e, axis=1)
        if np.all(size < 1e-12):
            break
        dq = _step(jac, e, size)
        big = np.max(np.abs(dq), axis=1, keepdims=True)
        dq *= np.minimum(1.0, max_step / np.maximum(big, 1e-300))
        qs = np.clip(qs + dq, lo, hi)
    full[:, chain.columns] = qs
    p, rot, _, _ = tool_jacobian(kin, tcp, chain, full)
    ep = np.linalg.norm(target_p - p, axis=1)
    eo = rotation_error(target_r, rot) if target_r is not None else np.zeros((len(qs), 3))
    return qs, ep, eo


def pose_ik(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray,
            position: np.ndarray, rotation: np.ndarray, *, limits: np.ndarray,
            position_tolerance: float, starts: int = 64, seed: int = 20240607
            ) -> tuple[IkSolution, ...]:
    """Every distinct solution within the joint limits putting the tool frame at
    ``position`` [m] with ``rotation`` (3, 3), each orientation component within
    ``limits`` [rad] (x, y, z of the goal frame; pi leaves an axis free) and the position
    within ``position_tolerance`` [m] (at least 1e-6). Seeded multi-start: the same
    request always gives the same solutions; () when none is found."""
    lim = kin.robot.position_limits(tuple(chain.joint_names))
    lower, upper = lim[:, 0], lim[:, 1]
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    init = rng.uniform(lo, hi, size=(starts, len(chain.joint_names)))
    init[0] = np.clip(q_base[chain.columns], lo, hi)
    rows = axis_rows([a for a, b in zip("xyz", limits) if b >= np.pi])
    qs, ep, eo = _solve(kin, tcp, chain, q_base, init, position, rotation, rows, lower,
                        upper, iterations=200, max_step=0.5)
    ok = (ep <= max(position_tolerance, 1e-6)) & np.all(np.abs(eo) <= limits + 1e-9, axis=1)
    found: list[tuple[np.ndarray, str]] = []
    for q in qs[ok]:
        for shifted in wrap_into_limits(q, lower, upper, chain.revolute):
            out = q_base.copy()
            out[chain.columns] = shifted
            found.append((out, ""))
    kept = dedupe(found, chain)
    kept.sort(key=lambda c: tuple(np.round(c[0][chain.columns], 9)))
    return tuple(IkSolution(q=q, branch=f"solution {k + 1}") for k, (q, _) in enumerate(kept))


def track_step(kin: Kinematics, tcp: Tcp, chain: Chain, q: np.ndarray, position: np.ndarray,
               rotation: np.ndarray | None, *, max_step: float = 0.05, iterations: int = 30,
               clamp: bool = True) -> tuple[np.ndarray, float, float]:
    """One local solve from the full joint vector ``q`` towards the tool frame at
    ``position`` (and ``rotation``, every axis, when given): (the new full vector, its
    position error [m], its largest orientation error [rad]). ``clamp``: within the
    joint position limits; without, the unbounded solution (to tell a limit from the
    workspace's edge)."""
    lim = kin.robot.position_limits(tuple(chain.joint_names))
    lower, upper = (lim[:, 0], lim[:, 1]) if clamp else (
        np.full(len(lim), -np.inf), np.full(len(lim), np.inf))
    rows = np.arange(3) if rotation is not None else np.zeros(0, np.int64)
    qs, ep, eo = _solve(kin, tcp, chain, q, q[chain.columns][None], position, rotation,
                        rows, lower, upper, iterations=iterations, max_step=max_step)
    out = q.copy()
    out[chain.columns] = qs[0]
    return out, float(ep[0]), float(np.max(np.abs(eo[0])))
