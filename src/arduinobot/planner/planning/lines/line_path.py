"""Following a straight tcp line with the joints: dense IK, no jumps, no bending.

:func:`follow_line` walks the segment from the start's tcp to the target with a local
solve per step from the previous state (:func:`arduinobot.planner.kinematics.ik_pose.track_step`),
so the joints stay on one IK branch; a group that can choose its orientation (six or
more joints moving the tcp) holds the start's orientation, a position-only group lets it
follow from the position. Every vertex is within the joint limits and collision-free, and
between two vertices the tcp (joints interpolated linearly) stays within
``deviation / 4`` of the line (a held orientation within ``MAX_TURN / 4``): a segment whose mid or quarter points stray further is
split at the line's own point. Where the walk cannot go on it raises
:class:`~arduinobot.contract.errors.LineInterrupted` with the fraction it reached, like MoveIt's
computeCartesianPath, instead of bending the line.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.errors import LineInterrupted
from arduinobot.description.tcp import Tcp
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.ik_numeric import Chain
from arduinobot.planner.kinematics.ik_pose import tool_jacobian, track_step
from arduinobot.planner.kinematics.rotations import rotation_error

log = logging.getLogger(__name__)

#: [m] the largest tcp step of the walk (vertices are then thinned or split)
WALK_STEP = 0.01
#: [m] a step is halved when a joint would move more than JUMP per WALK_STEP; below
#: this the joints would have to jump (a singularity or a branch change): refused
MIN_STEP = 1e-5
#: [rad] a joint move per WALK_STEP of tcp travel above this is accepted only where
#: the Jacobian predicts it (a fast, continuous turn); else the step is halved
JUMP = 0.25
#: [m] a solve counts as converged within this of the line's point
SOLVE_TOL = 1e-7
#: [rad] a held orientation stays this close to the start's (as the tcp to the line)
MAX_TURN = 1e-3


@dataclass(frozen=True)
class LinePath:
    """The joint path of a straight tcp line.

    Attributes:
        start, end: the tcp's line [m], shape (3,) each; ``length`` [m].
        vertices: joint states along it, shape (k, dof), first = the start state.
        fractions: each vertex's place along the line in [0, 1], shape (k,).
        rotation: the held tool rotation (3, 3), or None (orientation follows position).
        max_vertex_deviation: the largest tcp distance [m] from the line found on the
            joint-interpolated segments (mid and quarter points).
    """

    start: np.ndarray
    end: np.ndarray
    length: float
    vertices: np.ndarray
    fractions: np.ndarray
    rotation: np.ndarray | None
    max_vertex_deviation: float


def line_deviation(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance [m] of each point (m, 3) from the segment a-b."""
    d = b - a
    n2 = float(d @ d)
    t = np.clip(((points - a) @ d) / n2, 0.0, 1.0) if n2 > 0 else np.zeros(len(points))
    return np.linalg.norm(points - (a + t[:, None] * d), axis=1)


@dataclass(frozen=True)
class _Line:
    """One line being followed: what the walk and the refinement solve and check
    against, with the refusals they raise (each with the fraction reached)."""

    kin: Kinematics
    tcp: Tcp
    chain: Chain
    world: CollisionWorld
    p0: np.ndarray
    target: np.ndarray
    rot: np.ndarray | None
    length: float

    def point(self, f: float) -> np.ndarray:
        """The line's point [m] at fraction ``f``."""
        return self.p0 + f * (self.target - self.p0)

    def solve(self, q_from: np.ndarray, f: float, done: float) -> np.ndarray:
        """The state putting the tcp on the line's point at ``f``, solved from ``q_from``.

        Raises:
            LineInterrupted: a joint limit or the workspace's edge is in the way.
        """
        kin, tcp, chain, rot = self.kin, self.tcp, self.chain, self.rot
        q, err, oerr = track_step(kin, tcp, chain, q_from, self.point(f), rot)
        if err <= SOLVE_TOL and oerr <= 1e-6:
            return q
        # why not: a joint limit (the unbounded solve gets there) or the workspace's edge
        qf, err_f, oerr_f = track_step(kin, tcp, chain, q_from, self.point(f), rot,
                                       clamp=False)
        if err_f <= SOLVE_TOL and oerr_f <= 1e-6:
            lim = kin.robot.position_limits(tuple(chain.joint_names))
            vals = qf[chain.columns]
            i = int(np.argmax(np.maximum(lim[:, 0] - vals, vals - lim[:, 1])))
            joint = chain.joint_names[i]
            raise LineInterrupted(
                f"the line crosses {joint}'s limits [{lim[i, 0]:.4g}, {lim[i, 1]:.4g}] rad",
                fraction=done, reason="joint_limit",
                details={"joint": joint, "value": float(vals[i]),
                         "lower": float(lim[i, 0]), "upper": float(lim[i, 1]),
                         "position": self.point(done).tolist()})
        raise LineInterrupted(
            f"the line leaves the workspace near {np.round(self.point(f), 4).tolist()} "
            f"(the nearest the tcp gets is {err_f:.3g} m away)", fraction=done,
            reason="out_of_workspace",
            details={"position": self.point(done).tolist(), "nearest_distance": err_f})

    def check(self, q: np.ndarray, done: float) -> None:
        """Refuse a state in collision.

        Raises:
            LineInterrupted: ``q`` collides (with the pairs).
        """
        chk = self.world.check(q)
        if not chk.valid:
            pairs = [list(p) for p in chk.pairs]
            raise LineInterrupted(
                "the line runs into a collision: " + ", ".join(f"{a}/{b}" for a, b in
                                                               chk.pairs),
                fraction=done, reason="collision",
                details={"pairs": pairs, "position": self.point(done).tolist(),
                         "q": dict(zip(self.kin.joint_names, map(float, q)))})

    def continuous(self, qa: np.ndarray, qb: np.ndarray, dp: np.ndarray) -> bool:
        """Whether the step qa -> qb (tcp moving ``dp``) is a fast but continuous move."""
        # the line passing near the yaw axis: the step is what the Jacobian predicts to
        # first order; a jump to another branch is not
        _, _, jp, jw = tool_jacobian(self.kin, self.tcp, self.chain, qa[None])
        jac, rhs = (jp[0], dp) if self.rot is None else \
            (np.vstack([jp[0], jw[0]]), np.concatenate([dp, np.zeros(3)]))
        pred = np.linalg.lstsq(jac, rhs, rcond=1e-9)[0]
        miss = float(np.max(np.abs((qb - qa)[self.chain.columns] - pred)))
        return miss <= 0.1 * float(np.max(np.abs(pred))) + 1e-6


def _walk(line: _Line, start: np.ndarray) -> tuple[list[np.ndarray], list[float]]:
    """The vertices and their fractions of a walk along the whole line from ``start``,
    the step halved where the joints would jump and doubled back after.

    Raises:
        LineInterrupted: where the walk cannot go on, at the fraction bisected to.
    """
    length = line.length
    verts, fracs = [start.copy()], [0.0]
    f, q = 0.0, start.copy()
    step = min(WALK_STEP, length) / length
    while f < 1.0:
        nxt = min(1.0, f + step)
        try:
            q_new = line.solve(q, nxt, f)
            line.check(q_new, f)
        except LineInterrupted:
            # how far it really gets: bisect the step (to 1/64 of it), then refuse there
            lo, hi, q_lo = f, nxt, q
            for _ in range(6):
                mid = 0.5 * (lo + hi)
                try:
                    q_mid = line.solve(q_lo, mid, lo)
                    line.check(q_mid, lo)
                except LineInterrupted:
                    hi = mid
                else:
                    lo, q_lo = mid, q_mid
            line.check(line.solve(q_lo, hi, lo), lo)
            raise
        jump = float(np.max(np.abs(q_new - q)))
        if jump > JUMP * (nxt - f) * length / WALK_STEP + 1e-9 and \
                not line.continuous(q, q_new, (nxt - f) * (line.target - line.p0)):
            step /= 2
            if step * length < MIN_STEP:
                raise LineInterrupted(
                    "the joints would have to jump to stay on the line (a singularity "
                    "or the edge of an IK branch)", fraction=f, reason="singularity",
                    details={"position": line.point(f).tolist(), "joint_step": jump})
            continue
        verts.append(q_new)
        fracs.append(nxt)
        f, q = nxt, q_new
        step = min(WALK_STEP / length, step * 2)
    return verts, fracs


def _refine(line: _Line, verts: list[np.ndarray], fracs: list[float], *,
            deviation: float) -> tuple[list[np.ndarray], list[float], float]:
    """Split the walk's segments whose joint interpolation strays from the line (or a
    held orientation turns); the vertices, their fractions and the largest deviation
    [m] left on the segments.

    Raises:
        LineInterrupted: a split point cannot be solved or collides.
    """
    tol = deviation / 4
    out_v, out_f = [verts[0]], [fracs[0]]
    worst = 0.0
    stack = [(verts[i], fracs[i], verts[i + 1], fracs[i + 1])
             for i in range(len(verts) - 1)][::-1]
    while stack:
        qa, fa, qb, fb = stack.pop()
        probe = qa + np.array([0.25, 0.5, 0.75])[:, None] * (qb - qa)
        pts, rots, _, _ = tool_jacobian(line.kin, line.tcp, line.chain, probe)
        dev = float(line_deviation(pts, line.p0, line.target).max())
        turn = 0.0 if line.rot is None else float(np.max(np.linalg.norm(
            rotation_error(line.rot, rots), axis=1)))
        if (dev > tol or turn > MAX_TURN / 4) and (fb - fa) * line.length > 1e-4:
            fm = 0.5 * (fa + fb)
            qm = line.solve(0.5 * (qa + qb), fm, fa)
            line.check(qm, fa)
            stack += [(qm, fm, qb, fb), (qa, fa, qm, fm)]
            continue
        worst = max(worst, dev)
        out_v.append(qb)
        out_f.append(fb)
    return out_v, out_f, worst


def follow_line(kin: Kinematics, tcp: Tcp, chain: Chain, world: CollisionWorld,
                start: np.ndarray, target: np.ndarray, *, hold_orientation: bool,
                deviation: float = 1e-3) -> LinePath:
    """The joint path taking the tcp from where ``start`` puts it to ``target`` [m] on a
    straight line (see the module doc).

    Raises:
        LineInterrupted: the line leaves the workspace, crosses a joint limit or a
            collision, or needs a joint jump (with the fraction reached).
    """
    p0, r0, _, _ = tool_jacobian(kin, tcp, chain, start[None])
    p0, r0 = p0[0], r0[0]
    rot = r0 if hold_orientation else None
    length = float(np.linalg.norm(target - p0))
    if length < 1e-9:
        return LinePath(p0, target, 0.0, start[None].copy(), np.zeros(1), rot, 0.0)
    line = _Line(kin, tcp, chain, world, p0, target, rot, length)
    verts, fracs = _walk(line, start)
    out_v, out_f, worst = _refine(line, verts, fracs, deviation=deviation)
    log.debug("line of %.4g m: %d vertices, %.3g mm off on the segments", length,
              len(out_v), 1e3 * worst)
    return LinePath(p0, np.asarray(target, float), length, np.array(out_v),
                    np.array(out_f), rot, worst)


@dataclass(frozen=True)
class LineReport:
    """What a straight-line move did, for its reply.

    Attributes:
        start, end: the tcp's line [m]; ``length`` [m].
        max_deviation: the largest tcp distance [m] from the line over the whole timed
            motion (a fine time grid, by forward kinematics).
        vertices: IK states along the line the joint path goes through.
        peak: the tcp's largest speed [m/s], acceleration [m/s^2] and angular speed
            [rad/s]; ``limits``: the Cartesian limits applied (scaled) and their source.
        ratios: the worst ratio to each of them (<= 1).
    """

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    length: float
    max_deviation: float
    vertices: int
    peak: dict[str, float]
    limits: dict[str, object]
    ratios: dict[str, float]

    def to_dict(self) -> dict[str, object]:
        return {"start": list(self.start), "end": list(self.end), "length": self.length,
                "max_deviation": self.max_deviation, "fraction": 1.0,
                "vertices": self.vertices, "peak": dict(self.peak),
                "limits": dict(self.limits), "ratios": dict(self.ratios)}
