"""Position inverse kinematics of the tool centre point: every joint solution, or why none.

Two solvers behind one function, :func:`position_ik`:

- closed form, when the listed joints are a yaw joint followed by two parallel pitch
  joints perpendicular to it (the arduinobot, with its lateral offsets: joint_2's origin
  sits at x = -0.02 and the tcp at x = -0.13, so the arm plane is offset from the yaw
  axis). Up to four solutions: base front/back times elbow up/down.
- for any other chain, a deterministic, seeded multi-start damped-least-squares solver
  (:mod:`arduinobot.planner.kinematics.ik_numeric`), deduplicated.

Both return only solutions within the joint position limits; a point that is reachable
only outside them raises :class:`~arduinobot.contract.errors.GoalOutOfReach` saying so.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from arduinobot.contract.errors import GoalOutOfReach, InvalidRequest
from arduinobot.description.tcp import Tcp
from arduinobot.planner.checks import check_positions
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.ik_numeric import (
    Chain,
    build_chain,
    dedupe,
    nearest_distance,
    solve_dls,
    wrap_into_limits,
)

_log = logging.getLogger(__name__)

# Axes this close to parallel/perpendicular (|sin| or |cos| below it) count as exactly so.
_AXIS_EPS = 1e-9


@dataclass(frozen=True)
class IkSolution:
    """One joint solution.

    Attributes:
        q: the full actuated joint vector [rad or m] in ``kin.joint_names`` order, shape (dof,).
        branch: a readable label: "front/elbow_up" ... for the closed form, "solution k"
            for the numeric solver.
    """

    q: np.ndarray
    branch: str


def position_ik(
    kin: Kinematics,
    tcp: Tcp,
    position: ArrayLike,
    *,
    joints: Sequence[str] | None = None,
    q_fixed: ArrayLike | None = None,
    tolerance: float = 1e-6,
) -> tuple[IkSolution, ...]:
    """Every distinct joint solution within the position limits putting the tcp at ``position``.

    Args:
        kin: the robot's kinematics.
        tcp: the tool centre point (``parent_link`` and ``xyz`` [m] in that link).
        position: the target [m] in the root frame, shape (3,).
        joints: the joints to solve for (default: every actuated joint that moves the
            tcp's link); the others keep their ``q_fixed`` value.
        q_fixed: a full joint vector, shape (dof,), giving the joints not solved for
            (default all zero); it also seeds the numeric solver.
        tolerance: the largest accepted tcp position error [m].

    Returns:
        The solutions, sorted by branch (closed form) or joint values (numeric). A
        target on the first joint's axis (closed form) leaves that joint free: it keeps
        its ``q_fixed`` value.

    Raises:
        InvalidRequest: a malformed ``position``, ``joints``, ``q_fixed`` or ``tolerance``.
        JointLimitViolation: ``q_fixed`` puts a fixed joint outside its limits.
        GoalOutOfReach: no solution; ``details["reason"]`` is ``"out_of_workspace"`` or
            ``"outside_joint_limits"``, with the nearest tcp distance [m] the solver
            achieved with and without the limits (a best-found figure, not a bound).
    """
    target = _finite_vector(position, 3)
    if target is None:
        raise InvalidRequest(f"must be 3 finite numbers [m], got {position!r}", field="position")
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise InvalidRequest(f"must be a positive number of metres, got {tolerance!r}",
                             field="tolerance")
    q_base = np.zeros(kin.dof) if q_fixed is None else _finite_vector(q_fixed, kin.dof)
    if q_base is None:
        raise InvalidRequest(f"must be {kin.dof} finite joint values "
                             f"({', '.join(kin.joint_names)})", field="q_fixed")
    if joints is None:  # the robot's own: no joint names assumed
        joints = tuple(j.name for j in kin.robot.link_path(tcp.parent_link)
                       if j.movable and j.name in kin.joint_names)
    chain = build_chain(kin, tcp, joints)
    lim = kin.robot.position_limits(tuple(chain.joint_names))
    lower, upper = lim[:, 0], lim[:, 1]
    fixed = [i for i, n in enumerate(kin.joint_names) if n not in chain.joint_names]
    names = tuple(kin.joint_names[i] for i in fixed)
    check_positions(names, q_base[fixed], kin.robot.position_limits(names), field="q_fixed")

    geo = _geometric_model(kin, tcp, chain, q_base)
    if geo is not None:
        raw = _closed_form(geo, target, q_base[chain.columns])
        solver = "closed_form"
    else:
        raw = _numeric(kin, tcp, chain, q_base, target, lower, upper, tolerance)
        solver = "numeric"
    candidates, outside = _into_limits(kin, tcp, chain, q_base, target, raw, lower, upper,
                                       tolerance)
    kept = dedupe(candidates, chain)
    if not kept:
        raise _out_of_reach(kin, tcp, chain, q_base, target, lower, upper, outside, geo,
                            tolerance)
    # closed form: by branch, then joint values; numeric: by joint values, then numbered
    kept.sort(key=lambda c: (_BRANCHES.index(c[1]) if geo is not None else 0,
                             tuple(np.round(c[0][chain.columns], 9))))
    if solver == "numeric":
        kept = [(q, f"solution {k + 1}") for k, (q, _) in enumerate(kept)]
    _log.debug("position_ik %s: %d solutions (%s)", target, len(kept), solver)
    return tuple(IkSolution(q=q, branch=b) for q, b in kept)


def _numeric(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray,
             target: np.ndarray, lower: np.ndarray, upper: np.ndarray,
             tolerance: float) -> list[tuple[np.ndarray, str]]:
    """The numeric solver's solutions (chain joints, unlabelled): multi-start, once within
    the limits and once without (so a target reachable only outside them is told)."""
    starts = _starts(q_base[chain.columns], lower, upper)
    raw_q, err = solve_dls(kin, tcp, chain, q_base, target, starts, lower, upper,
                           clamp=True)
    free_q, free_err = solve_dls(kin, tcp, chain, q_base, target, starts, lower, upper,
                                 clamp=False)
    found = np.concatenate([raw_q[err <= tolerance], free_q[free_err <= tolerance]])
    return [(q, "") for q in found]


def _into_limits(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray,
                 target: np.ndarray, raw: Sequence[tuple[np.ndarray, str]],
                 lower: np.ndarray, upper: np.ndarray, tolerance: float
                 ) -> tuple[list[tuple[np.ndarray, str]], list[tuple[np.ndarray, str]]]:
    """The raw solutions reaching ``target`` as full joint vectors: those within the
    limits (revolute joints wrapped into them, every turn that fits) and those outside."""

    def full(q: np.ndarray) -> np.ndarray:  # q_base with the solved-for joints at q
        out = q_base.copy()
        out[chain.columns] = q
        return out

    candidates: list[tuple[np.ndarray, str]] = []
    outside: list[tuple[np.ndarray, str]] = []
    for q, label in raw:
        if np.linalg.norm(_fk(kin, tcp, full(q)) - target) > tolerance:
            continue
        q = np.where(chain.revolute, np.remainder(q + np.pi, 2 * np.pi) - np.pi, q)
        shifted = wrap_into_limits(q, lower, upper, chain.revolute)
        if not shifted:
            outside.append((full(q), label))
        candidates += [(full(qs), label) for qs in shifted]
    return candidates, outside


_BRANCHES = ("front/elbow_up", "front/elbow_down", "back/elbow_up", "back/elbow_down")


def _finite_vector(value: ArrayLike, n: int) -> np.ndarray | None:
    """``value`` as a new float array of shape (n,), or None if it is not n finite numbers."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        return None
    return a if a.shape == (n,) and np.all(np.isfinite(a)) else None


def _fk(kin: Kinematics, tcp: Tcp, q: np.ndarray) -> np.ndarray:
    return kin.point_position(q, tcp.parent_link, tcp.xyz)


def _starts(seed: np.ndarray, lower: np.ndarray, upper: np.ndarray, n: int = 48) -> np.ndarray:
    # Seeded so the same request always yields the same solutions.
    rng = np.random.default_rng(20240607)
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    starts = rng.uniform(lo, hi, size=(n, seed.shape[0]))
    starts[0] = np.clip(seed, lo, hi)
    return starts


@dataclass(frozen=True)
class _Geo:
    """The yaw + two parallel pitch joints structure, in a frame at the yaw axis.

    Local frame: origin on the yaw axis, z along it, x along the pitch axes at q = 0.
    The tcp's local x stays ``x_t``; its (y, z) is the complex number
    ``c2 + e^{i q2} (l1 + e^{i s3 q3} l2)``.
    """

    origin: np.ndarray
    frame: np.ndarray  # columns e_x, e_y, e_z
    x_t: float
    c2: complex
    l1: complex
    l2: complex
    s3: float


def _geometric_model(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray) -> _Geo | None:
    if len(chain.joint_names) != 3 or not all(chain.revolute) or not chain.ordered:
        return None
    q0 = q_base.copy()
    q0[chain.columns] = 0.0
    poses = kin.link_poses(q0)
    axes, points = [], []
    for name in chain.joint_names:
        j = kin.robot.joints[name]
        t = poses[kin.link_index[j.child]]
        axes.append(t[:3, :3] @ (np.asarray(j.axis, float) / np.linalg.norm(j.axis)))
        points.append(t[:3, 3])
    a1, a2, a3 = axes
    if abs(a1 @ a2) > _AXIS_EPS or np.linalg.norm(np.cross(a2, a3)) > _AXIS_EPS:
        return None
    frame = np.column_stack([a2, np.cross(a1, a2), a1])
    origin = points[0]

    def local(p: np.ndarray) -> np.ndarray:
        return frame.T @ (p - origin)

    pt = local(_fk(kin, tcp, q0))
    p2, p3 = local(points[1]), local(points[2])
    c2, c3, ct = complex(p2[1], p2[2]), complex(p3[1], p3[2]), complex(pt[1], pt[2])
    l1, l2 = c3 - c2, ct - c3
    if abs(l1) < 1e-12 or abs(l2) < 1e-12:
        return None  # a degenerate arm: let the numeric solver handle it
    return _Geo(origin=origin, frame=frame, x_t=float(pt[0]), c2=c2, l1=l1, l2=l2,
                s3=float(np.sign(a2 @ a3)))


def _acos_branches(c: float) -> list[float]:
    # Rounding may push a boundary point just past ±1; FK verification against the
    # tolerance decides whether such a point counts.
    if abs(c) > 1.0 + 1e-6:
        return []
    a = math.acos(max(-1.0, min(1.0, c)))
    return [a, -a]


def _closed_form(g: _Geo, target: np.ndarray, seed: np.ndarray) -> list[tuple[np.ndarray, str]]:
    x, y, z = g.frame.T @ (target - g.origin)
    r2 = x * x + y * y - g.x_t * g.x_t
    if r2 < -1e-12:
        return []
    ry = math.sqrt(max(r2, 0.0))
    out: list[tuple[np.ndarray, str]] = []
    for side, wy in (("front", ry), ("back", -ry)):
        if x * x + y * y < 1e-24 and abs(g.x_t) < 1e-12:
            q1 = float(seed[0])  # on the yaw axis: joint 1 is free, keep its given value
        else:
            q1 = math.atan2(y, x) - math.atan2(wy, g.x_t)
        u = complex(wy, z) - g.c2
        k = g.l1.conjugate() * g.l2
        c = (abs(u) ** 2 - abs(g.l1) ** 2 - abs(g.l2) ** 2) / (2 * abs(k))
        for a in _acos_branches(c):
            phi = a - np.angle(k)
            arm = g.l1 + np.exp(1j * phi) * g.l2
            q2 = float(np.angle(u) - np.angle(arm)) if abs(u) > 1e-12 else float(seed[1])
            elbow = np.exp(1j * q2) * g.l1  # elbow relative to the shoulder axis
            # "up" is the side of the shoulder-target line the yaw axis points to.
            normal = 1j * u if u.real > 0 else (-1j * u if u.real < 0 else complex(1, 0))
            up = (normal.conjugate() * elbow).real >= 0
            q = np.array([q1, q2, g.s3 * phi])
            q = (q + np.pi) % (2 * np.pi) - np.pi
            out.append((q, f"{side}/elbow_{'up' if up else 'down'}"))
    return out


def _out_of_reach(kin: Kinematics, tcp: Tcp, chain: Chain, q_base: np.ndarray,
                  target: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  outside: list[tuple[np.ndarray, str]], geo: _Geo | None,
                  tolerance: float) -> GoalOutOfReach:
    starts = _starts(q_base[chain.columns], lower, upper)
    within = nearest_distance(kin, tcp, chain, q_base, target, starts, lower, upper, clamp=True)
    details: dict[str, object] = {
        "position": target.tolist(), "joints": list(chain.joint_names),
        "tolerance": tolerance, "nearest_distance_within_limits": within,
    }
    if geo is not None:
        d_in, d_out = abs(abs(geo.l1) - abs(geo.l2)), abs(geo.l1) + abs(geo.l2)
        details["reach"] = {"min_distance_from_yaw_axis": abs(geo.x_t),
                            "shoulder_to_tcp_min": d_in, "shoulder_to_tcp_max": d_out}
    outside = dedupe(outside, chain)
    if outside:
        details["reason"] = "outside_joint_limits"
        details["solutions_outside_limits"] = [
            {n: float(q[c]) for n, c in zip(chain.joint_names, chain.columns)}
            for q, _ in outside]
        return GoalOutOfReach(
            f"position {target.tolist()} is reachable only outside the joint limits "
            f"({len(outside)} solution(s) found, none within limits; nearest tcp position "
            f"within limits is {within:.4g} m away)", details=details)
    # Both figures are the best the multi-start solver found; the unbounded one can be
    # no worse than the bounded one.
    free = min(within, nearest_distance(kin, tcp, chain, q_base, target, starts, lower, upper,
                                        clamp=False))
    details["reason"] = "out_of_workspace"
    details["nearest_distance"] = free
    return GoalOutOfReach(
        f"position {target.tolist()} is out of the workspace: the nearest reachable tcp "
        f"position is {free:.4g} m away ({within:.4g} m within the joint limits)",
        details=details)
