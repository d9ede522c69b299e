"""The generic part of position IK: which joints move the tcp, and a numeric solver.

:func:`solve_dls` runs damped least squares from many starts at once (one batched FK
call per iteration for all of them), so a robot of any shape gets its solutions in a
few tens of milliseconds, deterministically for given starts.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.tcp import Tcp
from arduinobot.planner.kinematics.chain import Kinematics

# Solutions closer than this in every joint [rad or m] are one solution.
DEDUPE_TOL = 1e-5
# Joint values this far past a limit [rad or m] are clipped onto it, not rejected.
LIMIT_SLACK = 1e-9


@dataclass(frozen=True)
class Chain:
    """The solved-for joints and how each moves the tcp.

    Attributes:
        joint_names: the solved-for joints, in the caller's order.
        columns: their indices in ``kin.joint_names``, shape (n,).
        revolute: per joint, True for revolute/continuous, False for prismatic.
        continuous: per joint, True when it has no position limits.
        ordered: the joints lie on the root-to-tcp path in the given order, without
            mimics of them on it (what the closed form needs).
        coupled: a mimic of a solved-for joint also moves the tcp.
        terms: per tree joint on the tcp path driven by a solved-for joint:
            (column in the chain, child link index, unit axis in the child frame,
            multiplier, revolute?).
        tcp_link: the tcp parent link's index in ``kin.link_names``.
    """

    joint_names: tuple[str, ...]
    columns: np.ndarray
    revolute: tuple[bool, ...]
    continuous: tuple[bool, ...]
    ordered: bool
    coupled: bool
    terms: tuple[tuple[int, int, np.ndarray, float, bool], ...]
    tcp_link: int


def build_chain(kin: Kinematics, tcp: Tcp, joints: Sequence[str]) -> Chain:
    """Validate ``joints`` and ``tcp`` against ``kin``. Raises InvalidRequest."""
    if tcp.parent_link not in kin.link_index:
        raise InvalidRequest(f"tcp parent link '{tcp.parent_link}' is not a link of "
                             f"'{kin.robot.name}'", field="tcp")
    names = tuple(joints)
    if not names or len(set(names)) != len(names):
        raise InvalidRequest(f"must be distinct joint names, got {list(names)}", field="joints")
    for n in names:
        if n not in kin.joint_names:
            raise InvalidRequest(f"'{n}' is not one of the actuated joints "
                                 f"({', '.join(kin.joint_names)})", field="joints")
    col = {n: i for i, n in enumerate(names)}
    terms = []
    order: list[str] = []
    coupled = False
    for j in kin.robot.link_path(tcp.parent_link):
        if not j.movable:
            continue
        leader, mult = (j.mimic.joint, j.mimic.multiplier) if j.mimic else (j.name, 1.0)
        if leader not in col:
            continue
        if j.type not in ("revolute", "continuous", "prismatic"):
            raise InvalidRequest(f"'{j.name}' is a {j.type} joint; position IK handles "
                                 "revolute, continuous and prismatic joints", field="joints")
        coupled |= j.mimic is not None
        order.append(j.name)
        axis = np.asarray(j.axis, float) / np.linalg.norm(j.axis)
        terms.append((col[leader], kin.link_index[j.child], axis, float(mult),
                      j.type != "prismatic"))
    moved = {names[t[0]] for t in terms}
    for n in names:
        if n not in moved:
            raise InvalidRequest(f"'{n}' does not move the tcp (link '{tcp.parent_link}')",
                                 field="joints")
    types = [kin.robot.joints[n].type for n in names]
    lim = kin.robot.position_limits(names)
    return Chain(
        joint_names=names,
        columns=np.array([kin.joint_names.index(n) for n in names], dtype=np.int64),
        revolute=tuple(t != "prismatic" for t in types),
        continuous=tuple(bool(t != "prismatic" and not np.all(np.isfinite(lim[i])))
                         for i, t in enumerate(types)),
        ordered=not coupled and tuple(order) == names,
        coupled=coupled,
        terms=tuple(terms),
        tcp_link=kin.link_index[tcp.parent_link],
    )


def solve_dls(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray, target: np.ndarray,
              starts: np.ndarray, lower: np.ndarray, upper: np.ndarray, *, clamp: bool,
              iterations: int = 150) -> tuple[np.ndarray, np.ndarray]:
    """Damped least squares from every start at once.

    Args:
        q_base: the full joint vector the solved-for joints are written into, shape (dof,).
        target: the tcp target [m], shape (3,).
        starts: initial values of the solved-for joints, shape (m, n).
        clamp: project onto [lower, upper] after each step (else solve unbounded).

    Returns:
        The final values, shape (m, n), and each one's tcp error [m], shape (m,).
    """
    qs = np.array(starts, dtype=float)
    m = qs.shape[0]
    full = np.tile(q_base, (m, 1))
    xyz = np.asarray(tcp.xyz, float)
    lo = np.where(np.isfinite(lower), lower, -np.inf)
    hi = np.where(np.isfinite(upper), upper, np.inf)
    err = np.full(m, np.inf)
    for _ in range(iterations + 1):
        full[:, chain.columns] = qs
        poses = kin.link_poses_batch(full)
        p = poses[:, chain.tcp_link, :3, :3] @ xyz + poses[:, chain.tcp_link, :3, 3]
        e = target - p
        new_err = np.linalg.norm(e, axis=1)
        # Stop when converged, or when no start improves any more.
        if np.all(new_err < 1e-13) or np.all(np.abs(err - new_err) < 1e-15):
            err = new_err
            break
        err = new_err
        jac = np.zeros((m, 3, qs.shape[1]))
        for c, link, axis, mult, rev in chain.terms:
            w = poses[:, link, :3, :3] @ axis
            if rev:
                jac[:, :, c] += mult * np.cross(w, p - poses[:, link, :3, 3])
            else:
                jac[:, :, c] += mult * w
        dq = _dls_step(jac, e, err)
        if clamp:
            # Joints at a limit that the step pushes outwards are held there and the
            # step is re-solved without them (an active set), so a start does not stall.
            held = ((qs <= lo) & (dq < 0)) | ((qs >= hi) & (dq > 0))
            if held.any():
                dq = _dls_step(jac * ~held[:, None, :], e, err)
        step = np.max(np.abs(dq), axis=1, keepdims=True)
        dq *= np.minimum(1.0, 0.5 / np.maximum(step, 1e-300))
        qs += dq
        if clamp:
            np.clip(qs, lo, hi, out=qs)
    return qs, err


def _dls_step(jac: np.ndarray, e: np.ndarray, err: np.ndarray) -> np.ndarray:
    # Levenberg-style damping: strong far away or near singularities, vanishing at a
    # solution so the last steps converge quadratically.
    # The floor keeps the system regular when a start has already converged or a joint
    # has no effect at this configuration.
    lam2 = np.clip(err, 1e-6, 0.1)[:, None, None] ** 2
    jt = jac.transpose(0, 2, 1)
    n = jac.shape[2]
    if n < 3:  # fewer joints than coordinates: solve the smaller normal equations
        return np.linalg.solve(jt @ jac + lam2 * np.eye(n), jt @ e[:, :, None])[:, :, 0]
    return (jt @ np.linalg.solve(jac @ jt + lam2 * np.eye(3), e[:, :, None]))[:, :, 0]


def nearest_distance(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray,
                     target: np.ndarray, starts: np.ndarray, lower: np.ndarray,
                     upper: np.ndarray, *, clamp: bool) -> float:
    """The smallest tcp distance [m] to ``target`` the multi-start solver reaches."""
    _, err = solve_dls(kin, tcp, chain, q_base, target, starts, lower, upper, clamp=clamp,
                       iterations=300)
    return float(np.min(err))


def wrap_into_limits(q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                     revolute: Sequence[bool]) -> list[np.ndarray]:
    """Every 2*pi shift of ``q`` (revolute joints) lying within the limits; [] if none.

    Joints without limits are wrapped into (-pi, pi].
    """
    options: list[list[float]] = []
    for v, lo, hi, rev in zip(q, lower, upper, revolute):
        if rev and not (math.isfinite(lo) and math.isfinite(hi)):
            w = math.remainder(float(v), 2 * math.pi)
            options.append([w])
            continue
        if rev:
            k_min = math.ceil((lo - LIMIT_SLACK - v) / (2 * math.pi))
            k_max = math.floor((hi + LIMIT_SLACK - v) / (2 * math.pi))
            shifts = range(k_min, k_max + 1)
        else:
            shifts = range(0, 1) if lo - LIMIT_SLACK <= v <= hi + LIMIT_SLACK else range(0)
        vals = [min(max(float(v) + 2 * math.pi * k, lo), hi) for k in shifts]
        if not vals:
            return []
        options.append(vals)
    return [np.array(c) for c in itertools.product(*options)]


def dedupe(candidates: Sequence[tuple[np.ndarray, str]], chain: Chain
           ) -> list[tuple[np.ndarray, str]]:
    """Drop candidates within DEDUPE_TOL of an earlier one (angles of unlimited joints
    compared modulo 2*pi)."""
    kept: list[tuple[np.ndarray, str]] = []
    wrap = np.array(chain.continuous)
    for q, label in candidates:
        for k, _ in kept:
            d = q[chain.columns] - k[chain.columns]
            d = np.where(wrap, np.remainder(d + np.pi, 2 * np.pi) - np.pi, d)
            if np.max(np.abs(d)) < DEDUPE_TOL:
                break
        else:
            kept.append((q, label))
    return kept
