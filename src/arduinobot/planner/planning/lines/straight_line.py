"""Straight-line moves (Pilz's LIN): the tcp along a segment, within the Cartesian limits.

:class:`StraightLine` plans a :class:`~arduinobot.planner.planning.goals.LineGoal` from rest:

1. the line's joint path by dense IK (:func:`~arduinobot.planner.planning.lines.line_path.follow_line`):
   every vertex within the joint limits and collision-free, the joints never jumping;
   where it cannot go on: :class:`~arduinobot.contract.errors.LineInterrupted` with the fraction;
2. certified: the polyline through the vertices is proven free over its whole length
   (:class:`~arduinobot.planner.collision.proof.certify.Certifier`), its corners blended and each blend
   proven (:func:`~arduinobot.planner.timing.curve.build_curve`): the proof covers every position
   the trajectory takes (a failed proof is a ``collision`` interruption at its place);
3. timed (:mod:`arduinobot.planner.planning.lines.line_timing`): one jerk-limited profile of the curve
   parameter, tightened until the verifier passes every joint limit (velocity,
   acceleration, jerk, effort) and the tcp's speed, acceleration (max_trans_acc speeding
   up, max_trans_dec slowing down) and angular speed are within the MoveIt config's
   ``pilz_cartesian_limits.yaml`` (defaults without one:
   :class:`arduinobot.description.moveit_config.CartesianLimits`), scaled by the request's
   scalings;
4. the tcp's deviation from the line, measured by forward kinematics on a fine time grid
   of the timed motion, must be at most ``max_deviation`` (1 mm): it is reported.

A group of six or more joints moving the tcp holds the start orientation along the line
(within ``MAX_TURN``, 1 mrad, on the same fine grid);
a position-only group (the arduinobot) turns as the position makes it (reported at the
end in ``reached``).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from arduinobot.contract.errors import (
    InvalidRequest,
    LineInterrupted,
    StartInCollision,
    TrajectoryError,
)
from arduinobot.description import Tcp
from arduinobot.description.moveit_config import CartesianLimits, read_cartesian_limits
from arduinobot.planner.collision.proof.certificate import Certificate, combine
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.ik_numeric import Chain, build_chain
from arduinobot.planner.kinematics.ik_pose import tool_jacobian
from arduinobot.planner.kinematics.rotations import rotation_error
from arduinobot.planner.planning.context import PlanningContext
from arduinobot.planner.planning.goal_states import resolve_group
from arduinobot.planner.planning.goals import LineGoal
from arduinobot.planner.planning.lines.line_path import (
    MAX_TURN,
    LinePath,
    LineReport,
    follow_line,
    line_deviation,
)
from arduinobot.planner.planning.lines.line_timing import Bounds, TcpMotion, line_timing, tcp_motion
from arduinobot.planner.planning.motion import MotionRequest, MotionResult
from arduinobot.planner.planning.strategy import moves_at_start
from arduinobot.planner.planning.tcp_goals import tcp_joints
from arduinobot.planner.timing.curve import Curve, build_curve
from arduinobot.planner.timing.trajectory import JointTrajectory
from arduinobot.planner.timing.verify import VerificationReport, Verifier

__all__ = ["StraightLine", "MAX_DEVIATION", "line_target"]

log = logging.getLogger(__name__)

#: [m] the largest tcp distance from the line a straight-line move may have
MAX_DEVIATION = 1e-3
#: timings tried before giving up (each tightens the bounds that were passed)
MAX_ATTEMPTS = 12
#: [rad] blends of the line's corners (the joint path turns a little at every vertex)
#: use at most this radius: small enough that the tcp stays near the line
BLEND_RADIUS = 0.05
#: kinematic chains of at least this many joints hold the tool's orientation on a line
ORIENTING_JOINTS = 6


def line_target(goal: LineGoal, p0: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """The line's end [m]: the goal's position, or the start tcp ``p0`` plus the offset
    (in the world frame, or in the tool frame ``r0`` (3, 3) at the start)."""
    if goal.position is not None:
        return np.asarray(goal.position, float)
    off = np.asarray(goal.offset, float)
    return p0 + (r0 @ off if goal.frame == "tcp" else off)


class StraightLine:
    """A straight tcp line from a start at rest (see the module doc).

    Args:
        max_deviation: [m] the tcp's largest distance from the line.
    """

    name = "straight line"

    def __init__(self, *, max_deviation: float = MAX_DEVIATION) -> None:
        self.max_deviation = max_deviation
        self._limits: dict[int, CartesianLimits] = {}

    def accepts(self, request: MotionRequest) -> bool:
        return not moves_at_start(request) and isinstance(request.goal, LineGoal)

    def cartesian_limits(self, context: PlanningContext) -> CartesianLimits:
        """The robot's Cartesian limits (its MoveIt config's file), read once."""
        key = id(context)
        if key not in self._limits:
            self._limits[key] = read_cartesian_limits(
                context.description.config.cartesian_limits)
        return self._limits[key]

    def solve(self, context: PlanningContext, request: MotionRequest) -> MotionResult:
        """Plan, certify, time and verify the line of ``request``.

        Raises:
            InvalidRequest, JointLimitViolation, StartInCollision: validation.
            LineInterrupted: the line cannot be followed all the way (``fraction``).
            TrajectoryError: no timing passed the joint and Cartesian limits.
        """
        goal = request.goal
        if not isinstance(goal, LineGoal):  # accepts() takes only these
            raise InvalidRequest(f"the straight-line strategy plans lines, not "
                                 f"{type(goal).__name__}", field="goal")
        t0 = time.perf_counter()
        d = context.description
        start = context.validate(request)
        world, paths = context.scene(request.obstacles, request.attached, request.clouds,
                                     ground=request.ground,
                                     allowed=request.allowed)
        chk = world.check(start)
        if not chk.valid:
            raise StartInCollision("the start state collides", pairs=chk.pairs,
                                   q=dict(zip(context.joint_names, map(float, start))))
        if d.tcp is None:
            raise InvalidRequest("the model has no tcp, so no line to move it along",
                                 field="goal.line")
        group = resolve_group(d, request.group, goal)
        joints = tcp_joints(d, paths.group_joints(group))
        kin = world.kin
        chain = build_chain(kin, d.tcp, joints)
        p0, r0, _, _ = tool_jacobian(kin, d.tcp, chain, start[None])
        target = line_target(goal, p0[0], r0[0])
        t1 = time.perf_counter()
        line = follow_line(kin, d.tcp, chain, world, start, target,
                           hold_orientation=len(joints) >= ORIENTING_JOINTS,
                           deviation=self.max_deviation)
        t2 = time.perf_counter()
        proof = Certifier(world, fraction=0.5)
        cert = proof.path(line.vertices)
        if not cert.free:
            k = cert.failure[0] if cert.failure else 0
            pair = cert.failure[2] if cert.failure else ("", "")
            raise LineInterrupted(f"the line runs into a collision: {pair[0]}/{pair[1]}",
                                  fraction=float(line.fractions[k]), reason="collision",
                                  details={"pairs": [list(pair)]})
        curve = build_curve(line.vertices, proof, max_radius=BLEND_RADIUS)
        cert = combine([cert, *(c.certificate for c in curve.corners
                                if c.certificate is not None)])
        t3 = time.perf_counter()
        vs, as_ = context.scaling(request)
        traj, report, motion, t_param, t_verify = self._time(
            context, request, curve, line, world, d.tcp, chain, cert, vs, as_)
        timing = {"validate": t1 - t0, "plan": t2 - t1, "simplify": 0.0,
                  "recheck": t3 - t2, "parameterise": t_param, "verify": t_verify}
        timing["total"] = time.perf_counter() - t0
        lim = self.cartesian_limits(context)
        ratios = motion.ratios(lim, vs, as_)
        dev = float(line_deviation(motion.positions, line.start, line.end).max())
        report_line = LineReport(
            start=tuple(map(float, line.start)), end=tuple(map(float, line.end)),  # type: ignore[arg-type]
            length=line.length, max_deviation=dev, vertices=len(line.vertices),
            peak={"velocity": float(np.linalg.norm(motion.velocities, axis=1).max()),
                  "acceleration": float(np.linalg.norm(motion.accelerations, axis=1).max()),
                  "angular_velocity": float(np.linalg.norm(motion.angular, axis=1).max())},
            limits={"max_trans_vel": lim.max_trans_vel * vs,
                    "max_trans_acc": lim.max_trans_acc * as_,
                    "max_trans_dec": lim.max_trans_dec * as_,
                    "max_rot_vel": lim.max_rot_vel * vs, "source": lim.source},
            ratios=ratios)
        return MotionResult(trajectory=traj, path=line.vertices, timing=timing,
                            verification=report, planner=self.name, line=report_line)

    def _time(self, context: PlanningContext, request: MotionRequest, curve: Curve,
              line: LinePath, world: CollisionWorld, tcp: Tcp, chain: Chain,
              cert: Certificate, vs: float, as_: float
              ) -> tuple[JointTrajectory, VerificationReport, TcpMotion, float, float]:
        """Time ``curve`` until the verifier and the tcp check pass: the trajectory, its
        report, the tcp's motion and the seconds spent timing and verifying."""
        # bounds from the curve's largest joint and tcp rates per unit of s, then
        # tightened by each ratio the verifier or the tcp check finds over 1
        lim = context.limits(vs, as_)
        cart = self.cartesian_limits(context)
        sec = curve.sections
        dq = np.concatenate([c(np.linspace(0, c.length, 64), 1) for c in sec])
        qs = np.concatenate([c(np.linspace(0, c.length, 64)) for c in sec])
        _, _, jp, _ = tool_jacobian(world.kin, tcp, chain, qs)
        rate = float(np.linalg.norm(np.einsum("mij,mj->mi", jp, dq[:, chain.columns]),
                                    axis=1).max()) or 1.0
        joint = float(np.abs(dq).max()) or 1.0
        bounds = Bounds(
            velocity=min(cart.max_trans_vel * vs / rate, float(np.min(lim.velocity)) / joint),
            acceleration=min(min(cart.max_trans_acc, -cart.max_trans_dec) * as_ / rate,
                             float(np.min(lim.acceleration)) / joint),
            jerk=float(np.min(lim.jerk)) / joint)
        dynamics, profiles = context.payload(world.attached)  # with what it carries
        timer = profiles[request.profile]
        verifier = Verifier(lim, dynamics, world,
                            clearance_states=context.clearance_states)
        t_param = t_verify = 0.0
        last = None
        for attempt in range(1, MAX_ATTEMPTS + 1):
            ta = time.perf_counter()
            timing = line_timing(curve, bounds)
            traj = JointTrajectory.sample(timing, dynamics.torques_batch,
                                          joint_names=context.joint_names,
                                          sample_rate=request.sample_rate,
                                          profile=request.profile,
                                          max_samples=request.max_samples)
            tb = time.perf_counter()
            report = verifier.verify(traj, enforce_jerk=timer.enforce_jerk,
                                     attempts=attempt, certificate=cert)
            motion = tcp_motion(world.kin, chain, tcp, timing)
            ratios = dict(motion.ratios(cart, vs, as_))
            tc = time.perf_counter()
            t_param += tb - ta
            t_verify += tc - tb
            dev = float(line_deviation(motion.positions, line.start, line.end).max())
            if dev > self.max_deviation:
                raise TrajectoryError(
                    f"the tcp strays {1e3 * dev:.3g} mm from the line (at most "
                    f"{1e3 * self.max_deviation:.3g} mm)", details={"max_deviation": dev})
            if line.rotation is not None:
                turn = float(np.linalg.norm(rotation_error(line.rotation, motion.rotations),
                                            axis=1).max())
                if turn > MAX_TURN:
                    raise TrajectoryError(
                        f"the tool turns {turn:.3g} rad off its held orientation (at most "
                        f"{MAX_TURN:g})", details={"max_turn": turn})
            if not report.collision_free or "position" in report.violations:
                raise TrajectoryError("the line's timing left its certified curve",
                                      details={"report": report.to_dict()})
            over = {k: report.worst[k] for k in report.violations}
            over.update({k: r for k, r in ratios.items() if r > 1.0 + 1e-6})
            last = (report, ratios)
            if not over:
                return traj, report, motion, t_param, t_verify
            log.info("line timing attempt %d over its limits: %s", attempt, over)

            def f(key: str, over: dict[str, float] = over) -> float:
                r = over.get(key, 0.0)
                return 0.98 / r if r > 1.0 and math.isfinite(r) else (0.5 if r > 1.0 else 1.0)
            fv = min(f("velocity"), f("tcp_velocity"), f("tcp_rotation"))
            fa = min(f("acceleration"), f("tcp_acceleration"), f("effort"))
            fj = f("jerk")
            bounds = bounds.scaled(velocity=min(fv, math.sqrt(fa), fj ** (1 / 3)),
                                   acceleration=min(fa, math.sqrt(fj)), jerk=fj)
        report, ratios = last  # type: ignore[misc]
        raise TrajectoryError("no timing of the line passed the joint and Cartesian limits",
                              details={"profile": request.profile,
                                       "report": report.to_dict(), "tcp_ratios": ratios})
