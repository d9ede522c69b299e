"""The motion pipeline: validate, plan a path, blend it, time it, verify it, return it.

:class:`MotionPlanner` is what the service calls. It keeps everything that is slow to
build: one :class:`CollisionWorld` (and path planner) per obstacle set, the scaled joint
limits per scaling pair, the inverse dynamics and toppra's constraint objects.

A trajectory is returned only if the :class:`~planner.timing.verify.Verifier` passes it. When a
check fails (toppra enforces limits only at gridpoints; ruckig's per-piece bounds are
conservative but sampled), the violated limits are derated by ``0.98 / ratio`` and the
path is re-timed, up to ``MAX_ATTEMPTS`` times; a collision along the blended curve falls
back to stopping at every waypoint (straight, re-checked edges). Otherwise
:class:`TrajectoryError` carries the last report.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping

import numpy as np

from description import Description

from ..cache import ArtifactCache
from ..checks import check_joint_names, check_positions
from ..collision.acm_proof import proven_never_pairs
from ..collision.certify import Certificate, Certifier, combine
from ..collision.world import CollisionWorld
from ..errors import InvalidRequest, TrajectoryError
from ..kinematics.dynamics import InverseDynamics
from ..kinematics.limits import JointLimits
from ..path_limits import ActiveLimits, Derating
from ..scene import Obstacle
from ..timing.curve import Curve, build_curve
from ..timing.ruckig_timing import JerkLimitedTiming
from ..timing.toppra_timing import TimeOptimalTiming
from ..timing.trajectory import CurveTiming, JointTrajectory
from ..timing.verify import VerificationReport, Verifier, derate
from .goals import resolve_group
from .motion import MotionRequest, MotionResult, Profile
from .paths import PathPlanner, PathRequest

log = logging.getLogger(__name__)

MAX_ATTEMPTS = 8


def _number(value: object, field: str, lo: float, hi: float, *, open_lo: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(float(value)):
        raise InvalidRequest(f"{value!r} is not a finite number", field=field)
    v = float(value)
    if (v <= lo if open_lo else v < lo) or v > hi:
        raise InvalidRequest(f"{v!r} must be in {'(' if open_lo else '['}{lo:g}, {hi:g}]",
                             field=field)
    return v


def _obstacle_key(obstacles: tuple[Obstacle, ...]) -> tuple:
    # ``where`` only names the field in errors; the geometry is what matters
    return tuple((o.id, o.shape, o.size, o.radius, o.length, o.mesh_path, o.xyz, o.rpy)
                 for o in obstacles)


class MotionPlanner:
    """Plans verified trajectories for one robot.

    Args:
        description: the robot.
        padding: collision padding [m] of every world built.
        max_worlds: obstacle sets whose worlds are kept (least recently used dropped).
        clearance_states: states the reported clearance is measured on (FCL distance
            queries cost ~10 ms each here; collision-freedom is checked on every state).
        cache: keeps what is slow to compute between runs (each link's OBB tree; the
            pairs proven never to collide of a robot without an SRDF), keyed by content.
    """

    def __init__(self, description: Description, *, padding: float = 0.0,
                 max_worlds: int = 8, clearance_states: int = 1,
                 cache: ArtifactCache | None = None) -> None:
        self.description = description
        self.cache = cache
        self.clearance_states = clearance_states
        self.padding = padding
        self.max_worlds = max_worlds
        self._worlds: dict[tuple, tuple[CollisionWorld, PathPlanner]] = {}
        self._robot_world: CollisionWorld | None = None
        base = self.world(())
        self.joint_names: tuple[str, ...] = tuple(base.kin.joint_names)
        self.dynamics = InverseDynamics(description.robot)
        self._limits: dict[tuple[float, float], JointLimits] = {}
        self.jerk_limited = JerkLimitedTiming(self.dynamics)
        self.time_optimal = TimeOptimalTiming(self.dynamics)
        full = self.limits(1.0, 1.0)
        self._lower = np.asarray(full.lower, float)
        self._upper = np.asarray(full.upper, float)
        # build toppra's constraint objects for the unscaled limits now, not on a request
        self.time_optimal.constraints(ActiveLimits.from_limits(full))

    # -- caches -----------------------------------------------------------------------
    def world(self, obstacles: tuple[Obstacle, ...]) -> CollisionWorld:
        """The collision world for ``obstacles``, built once per distinct obstacle set."""
        return self._entry(obstacles)[0]

    def _entry(self, obstacles: tuple[Obstacle, ...]) -> tuple[CollisionWorld, PathPlanner]:
        key = _obstacle_key(obstacles)
        found = self._worlds.pop(key, None)
        if found is None:
            w = self._base_world().with_scene(obstacles)
            found = (w, PathPlanner(w, self.description))
        self._worlds[key] = found  # most recently used last
        while len(self._worlds) > self.max_worlds:
            self._worlds.pop(next(iter(self._worlds)))
        return found

    def _base_world(self) -> CollisionWorld:
        # The robot-only world is built once; every obstacle set shares its geometry.
        if self._robot_world is None:
            world = CollisionWorld(self.description, padding=self.padding, cache=self.cache)
            if self.description.srdf is None:
                # No SRDF: beyond the joint-connected pairs, skip only pairs proven apart
                # everywhere in the joint limits (farther than the padding).
                never = proven_never_pairs(world, cache=self.cache,
                                           margin=self.padding + 1e-3)
                world = world.with_scene((), acm=world.acm.with_pairs(
                    never, reason="Never-proven"))
            self._robot_world = world
        return self._robot_world

    def limits(self, velocity_scaling: float, acceleration_scaling: float) -> JointLimits:
        key = (velocity_scaling, acceleration_scaling)
        lim = self._limits.get(key)
        if lim is None:
            lim = JointLimits.from_description(self.description,
                                               velocity_scaling=velocity_scaling,
                                               acceleration_scaling=acceleration_scaling)
            if len(self._limits) > 32:
                self._limits.pop(next(iter(self._limits)))
            self._limits[key] = lim
        return lim

    def scaling(self, request: MotionRequest) -> tuple[float, float]:
        """The request's (velocity, acceleration) scaling, or the MoveIt config's
        default for each one it leaves unset."""
        d = self.description
        return (d.default_velocity_scaling if request.velocity_scaling is None
                else request.velocity_scaling,
                d.default_acceleration_scaling if request.acceleration_scaling is None
                else request.acceleration_scaling)

    # -- validate ---------------------------------------------------------------------
    def validate(self, req: MotionRequest) -> np.ndarray:
        """Check every field; the start vector [rad], shape (dof,)."""
        resolve_group(self.description, req.group, req.goal)
        if not isinstance(req.obstacles, tuple) or \
                not all(isinstance(o, Obstacle) for o in req.obstacles):
            raise InvalidRequest("must be a tuple of Obstacle", field="obstacles")
        ids = [o.id for o in req.obstacles]
        if len(set(ids)) != len(ids):
            raise InvalidRequest("obstacle ids must be unique", field="obstacles")
        if not isinstance(req.planner, str) or not req.planner:
            raise InvalidRequest(f"{req.planner!r} is not a planner name", field="planner")
        _number(req.planning_time, "planning_time", 0.0, 60.0, open_lo=True)
        for name in ("velocity_scaling", "acceleration_scaling"):
            if getattr(req, name) is not None:
                _number(getattr(req, name), name, 0.0, 1.0, open_lo=True)
        _number(req.sample_rate, "sample_rate", 1.0, 1000.0, open_lo=False)
        if req.profile not in ("jerk_limited", "time_optimal"):
            raise InvalidRequest(f"'{req.profile}' is not one of jerk_limited, time_optimal",
                                 field="profile")
        if req.seed is not None and (isinstance(req.seed, bool) or not isinstance(req.seed, int)
                                     or req.seed < 0):
            raise InvalidRequest(f"{req.seed!r} must be an integer >= 0", field="seed")
        start = np.zeros(len(self.joint_names))
        if req.start is None:
            return start
        if not isinstance(req.start, Mapping):
            raise InvalidRequest("must map joint names to values [rad]", field="start")
        check_joint_names(self.description, req.start, field="start")
        for name, value in req.start.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(float(value)):
                raise InvalidRequest(f"{value!r} is not a finite number [rad]",
                                     field=f"start.{name}")
            start[self.joint_names.index(name)] = float(value)
        check_positions(self.joint_names, start, np.column_stack([self._lower, self._upper]),
                        field="start")
        return start

    # -- solve ------------------------------------------------------------------------
    def solve(self, request: MotionRequest) -> MotionResult:
        """Plan, time and verify a motion.

        Raises:
            InvalidRequest, JointLimitViolation, StartInCollision, GoalInCollision,
            GoalOutOfReach, NoPathFound: from validation and path planning.
            TrajectoryError: no timing passed verification (details hold the report).
        """
        if request.start_velocity is not None or request.start_acceleration is not None:
            from .moving_start import solve_moving  # a moving start: blend into it
            return solve_moving(self, request)
        t0 = time.perf_counter()
        start = self.validate(request)
        world, paths = self._entry(request.obstacles)
        t1 = time.perf_counter()
        res = paths.solve(PathRequest(start=start, goal=request.goal, group=request.group,
                                      planner=request.planner,
                                      planning_time=request.planning_time, seed=request.seed))
        t2 = time.perf_counter()
        # blends certified as they are made; with the path's proof, that certifies the
        # whole curve: its straight parts lie on the path's proven segments
        curve = build_curve(res.path, paths.proof)
        proof = combine([res.certificate, *(c.certificate for c in curve.corners
                                            if c.certificate is not None)]) \
            if res.certificate else None
        t3 = time.perf_counter()
        lim = self.limits(*self.scaling(request))
        traj, report, t_param, t_verify = self.time_path(curve, res.path, world, lim,
                                                         profile=request.profile,
                                                         sample_rate=request.sample_rate,
                                                         certificate=proof,
                                                         max_samples=request.max_samples)
        pt = res.timings
        timing = {
            "validate": (t1 - t0) + pt.get("validate", 0.0),
            "plan": pt.get("straight_line", 0.0) + pt.get("plan", 0.0),
            "simplify": pt.get("simplify", 0.0),
            "recheck": pt.get("recheck", 0.0) + (t3 - t2),
            "parameterise": t_param,
            "verify": t_verify,
        }
        timing["total"] = time.perf_counter() - t0
        return MotionResult(trajectory=traj, path=np.array(res.path), timing=timing,
                            verification=report, planner=res.planner)

    def time_path(self, curve: Curve, path: np.ndarray, world: CollisionWorld,
                  limits: JointLimits, *, profile: Profile = "jerk_limited",
                  sample_rate: float = 100.0, certificate: Certificate | None = None,
                  max_samples: int | None = None
                  ) -> tuple[JointTrajectory, VerificationReport, float, float]:
        """Time ``curve`` (blended from ``path``), verify, derate until it passes.

        ``certificate``: a proof that covers ``curve`` and every segment of ``path`` (the
        fallback stops at the waypoints), e.g. the path's and its blends' combined;
        without it the curve is certified here.

        Returns the trajectory, its report and the seconds spent timing and verifying.
        """
        verifier = Verifier(limits, self.dynamics, world,
                            clearance_states=self.clearance_states)
        # The trajectory's positions are its curve's points whatever the timing, so the
        # curve's certificate decides collisions: proven once per curve, reused across
        # derated timings (fraction 0.5 also certifies a clearance worth reporting).
        certifier = Certifier(world, fraction=0.5)
        certificates: dict[tuple[int, ...], tuple[Certificate, tuple]] = {}

        given = certificate

        def certificate(timing: CurveTiming) -> Certificate:
            if given is not None:
                return given
            curves = tuple(c for c, _ in timing.sections)
            key = tuple(map(id, curves))
            if key not in certificates:
                certificates[key] = (certifier.curve(curves), curves)
            return certificates[key][0]

        derating = Derating()
        t_param = t_verify = 0.0
        report: VerificationReport | None = None
        for attempt in range(1, MAX_ATTEMPTS + 1):
            a = time.perf_counter()
            active = ActiveLimits.from_limits(limits, derating)
            timing: CurveTiming
            if profile == "time_optimal":
                timing = self.time_optimal.parameterise(curve, active)
            else:
                timing = self.jerk_limited.parameterise(curve, active)
                if any(c.kind == "blend" for c in curve.corners):
                    # conservative per-piece bounds can make a sharp blend slower than
                    # stopping at the corner on straight, re-checked edges: keep the faster
                    stops = self.jerk_limited.parameterise(
                        build_curve(path, None, max_radius=0.0), active)
                    if stops.duration < timing.duration:
                        timing = stops
            traj = JointTrajectory.sample(timing, self.dynamics.torques_batch,
                                          joint_names=self.joint_names,
                                          sample_rate=sample_rate, profile=profile,
                                          max_samples=max_samples)
            b = time.perf_counter()
            report = verifier.verify(traj, enforce_jerk=profile == "jerk_limited",
                                     derating=derating, attempts=attempt,
                                     certificate=certificate(timing))
            c = time.perf_counter()
            t_param += b - a
            t_verify += c - b
            if report.ok:
                return traj, report, t_param, t_verify
            log.info("attempt %d failed verification: %s", attempt, report.violations or
                     "collision")
            if not report.collision_free or "position" in report.violations:
                if any(c.kind == "blend" for c in curve.corners):
                    # stop at every waypoint: the straight edges were certified
                    curve = build_curve(path, None, max_radius=0.0)
                    continue
                break
            derating = derate(report, derating)
        raise TrajectoryError("no timing of the path passed verification",
                              details={"profile": profile,
                                       "report": report.to_dict() if report else None})
