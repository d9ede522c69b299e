"""What every planning strategy plans with, built once per robot.

:class:`PlanningContext` keeps everything that is slow to build (one
:class:`CollisionWorld` and path planner per obstacle set and carried objects, the scaled
joint limits per scaling pair, the inverse dynamics and one instance of every timing
profile, per payload carried) and the stages
every strategy shares: checking a request (:meth:`~PlanningContext.validate`) and timing
a blended path until the verifier passes it (:meth:`~PlanningContext.time_path`).

It knows nothing of the strategies: they sit above it and call down into it, and
:class:`arduinobot.planner.planning.pipeline.MotionPlanner` picks one per request.

A trajectory is returned only if the :class:`~arduinobot.planner.timing.verify.Verifier` passes it.
When a check fails (toppra enforces limits only at gridpoints; ruckig's per-piece bounds
are conservative but sampled), the violated limits are derated by ``0.98 / ratio`` and
the path is re-timed, up to ``MAX_ATTEMPTS`` times; a collision along the blended curve
falls back to stopping at every waypoint (straight, re-checked edges). Otherwise
:class:`TrajectoryError` carries the last report.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping

import numpy as np

from arduinobot.contract.errors import InvalidRequest, TrajectoryError
from arduinobot.contract.ranges import check_range
from arduinobot.description import Description
from arduinobot.planner.cache import ArtifactCache
from arduinobot.planner.checks import check_joint_names, check_positions
from arduinobot.planner.collision.acm_proof import proven_never_pairs
from arduinobot.planner.collision.proof.certificate import Certificate
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.dynamics import InverseDynamics
from arduinobot.planner.kinematics.limits import JointLimits
from arduinobot.planner.path_limits import ActiveLimits, Derating
from arduinobot.planner.planning.goal_states import resolve_group
from arduinobot.planner.planning.motion import MotionRequest, Profile
from arduinobot.planner.planning.pathfinding.paths import PathPlanner
from arduinobot.planner.planning.pathfinding.search import check_seed
from arduinobot.planner.timing.curve import Curve, build_curve
from arduinobot.planner.timing.profiles import TimingProfile, build_profiles
from arduinobot.planner.timing.trajectory import CurveTiming, JointTrajectory
from arduinobot.planner.timing.verify import VerificationReport, Verifier, derate
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.ground import GROUND_ID, with_ground
from arduinobot.scene.obstacles import AttachedObject, Obstacle, resolve_attached

log = logging.getLogger(__name__)

MAX_ATTEMPTS = 8


def _obstacle_key(obstacles: tuple[Obstacle, ...]) -> tuple:
    # ``where`` only names the field in errors; the geometry is what matters
    return tuple(o.key() for o in obstacles)


def _attached_key(attached: tuple[AttachedObject, ...]) -> tuple:
    # the payload too: a world's carried objects decide the dynamics its motions are
    # timed and verified with (time_path reads them from the world)
    return tuple(a.shape_key() + a.payload_key() for a in attached)


class _CurveProofs:
    """The certificate of each curve a timing follows, proven once per curve.

    The trajectory's positions are its curve's points whatever the timing, so the
    curve's certificate decides collisions: proven once, reused across derated timings
    (fraction 0.5 also certifies a clearance worth reporting). ``given``: a proof that
    already covers every curve the timing may follow.
    """

    def __init__(self, world: CollisionWorld, given: Certificate | None) -> None:
        self.given = given
        self.certifier = Certifier(world, fraction=0.5)
        # the curves are kept with their proof so their ids stay theirs
        self.proofs: dict[tuple[int, ...], tuple[Certificate, tuple]] = {}

    def __call__(self, timing: CurveTiming) -> Certificate:
        if self.given is not None:
            return self.given
        curves = tuple(c for c, _ in timing.sections)
        key = tuple(map(id, curves))
        if key not in self.proofs:
            self.proofs[key] = (self.certifier.curve(curves), curves)
        return self.proofs[key][0]


class PlanningContext:
    """The robot's planning resources and shared stages (see the module doc).

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
        # payload key -> (dynamics, profiles) with those payloads (least recently used
        # dropped past max_worlds)
        self._payloads: dict[tuple, tuple[InverseDynamics, dict[str, TimingProfile]]] = {}
        self._robot_world: CollisionWorld | None = None
        base = self.world(())
        #: the robot's kinematics (every world's are the same robot's)
        self.kin = base.kin
        self.joint_names: tuple[str, ...] = tuple(base.kin.joint_names)
        self.dynamics = InverseDynamics(description.robot)
        self._limits: dict[tuple[float, float], JointLimits] = {}
        self.profiles: dict[str, TimingProfile] = build_profiles(self.dynamics)
        full = self.limits(1.0, 1.0)
        self._lower = np.asarray(full.lower, float)
        self._upper = np.asarray(full.upper, float)
        # build what a profile needs for the unscaled limits now, not on a request
        for profile in self.profiles.values():
            profile.prepare(ActiveLimits.from_limits(full))

    # -- caches -----------------------------------------------------------------------
    def world(self, obstacles: tuple[Obstacle, ...],
              attached: tuple[AttachedObject, ...] = (),
              clouds: tuple[CloudObstacle, ...] = (), *,
              ground: bool = True,
              allowed: tuple[tuple[str, str], ...] = ()) -> CollisionWorld:
        """The collision world for ``obstacles``, the ``attached`` objects carried and
        the ``clouds``' cells (and the ground unless ``ground`` is false), built once per
        distinct set of the four (and of the ``allowed`` pairs)."""
        return self.scene(obstacles, attached, clouds, ground=ground, allowed=allowed)[0]

    def scene(self, obstacles: tuple[Obstacle, ...],
              attached: tuple[AttachedObject, ...] = (),
              clouds: tuple[CloudObstacle, ...] = (), *, ground: bool = True,
              allowed: tuple[tuple[str, str], ...] = ()
              ) -> tuple[CollisionWorld, PathPlanner]:
        """The collision world for ``obstacles``, the ``attached`` objects carried and
        the ``clouds``' cells, and the path planner in it, built once per distinct set of
        the three (a cloud by its cells' content). ``ground``: the plane the base stands
        on (:mod:`arduinobot.scene.ground`) is an obstacle too, unless ``obstacles`` has
        one of its id already (a user's own ground replaces ours). ``allowed``: (object,
        obstacle) id pairs not checked in this world (an object resting on its support)."""
        obstacles = with_ground(obstacles, ground)
        allowed = tuple(sorted((min(a, b), max(a, b)) for a, b in allowed))
        key = (_obstacle_key(obstacles), _attached_key(attached),
               tuple((c.id, c.key()) for c in clouds), allowed)
        found = self._worlds.pop(key, None)
        if found is None:
            base = self._base_world()
            w = base.with_scene(obstacles, attached=attached, clouds=clouds,
                                acm=base.acm.with_pairs(allowed, reason="Resting")
                                if allowed else None)
            found = (w, PathPlanner(w, self.description))
        self._worlds[key] = found  # most recently used last
        while len(self._worlds) > self.max_worlds:
            self._worlds.pop(next(iter(self._worlds)))
        return found

    def payload(self, attached: tuple[AttachedObject, ...] = ()
                ) -> tuple[InverseDynamics, dict[str, TimingProfile]]:
        """The inverse dynamics with the ``attached`` objects' masses on their links, and
        the timing profiles built on it (the robot's own without a payload): what the
        verifier and the effort-limited timing of a motion carrying them use."""
        payloads = tuple(a.payload() for a in attached if a.mass > 0)
        if not payloads:
            return self.dynamics, self.profiles
        key = tuple(a.payload_key() for a in attached if a.mass > 0)
        found = self._payloads.pop(key, None)
        if found is None:
            dyn = self.dynamics.with_payloads(payloads)
            profiles = build_profiles(dyn)
            full = ActiveLimits.from_limits(self.limits(1.0, 1.0))
            for profile in profiles.values():
                profile.prepare(full)
            found = (dyn, profiles)
        self._payloads[key] = found
        while len(self._payloads) > self.max_worlds:
            self._payloads.pop(next(iter(self._payloads)))
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
            # the base stands on the ground: links that never move may touch it (a
            # static pair in contact would make every state collide)
            on_ground = [(GROUND_ID, n) for n, still in
                         zip(world.bodies.names, world.bodies.statics) if still]
            world = world.with_scene((), acm=world.acm.with_pairs(on_ground, reason="Ground"))
            self._robot_world = world
        return self._robot_world

    def limits(self, velocity_scaling: float, acceleration_scaling: float) -> JointLimits:
        """The joint limits scaled by the two factors, built once per pair."""
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
        # never plan as if an object the robot holds were not there: each checked here
        resolve_attached(self.description, req.attached, obstacles=req.obstacles)
        if not isinstance(req.planner, str) or not req.planner:
            raise InvalidRequest(f"{req.planner!r} is not a planner name", field="planner")
        check_range(req.planning_time, "planning_time")
        if req.velocity_scaling is not None:
            check_range(req.velocity_scaling, "velocity_scaling")
        if req.acceleration_scaling is not None:
            check_range(req.acceleration_scaling, "acceleration_scaling")
        check_range(req.sample_rate, "sample_rate")
        if req.profile not in self.profiles:
            raise InvalidRequest(f"'{req.profile}' is not one of "
                                 f"{', '.join(self.profiles)}", field="profile")
        check_seed(req.seed)
        return self._start(req.start)

    def _start(self, given: Mapping[str, float] | None) -> np.ndarray:
        start = np.zeros(len(self.joint_names))
        if given is None:
            return start
        if not isinstance(given, Mapping):
            raise InvalidRequest("must map joint names to values [rad]", field="start")
        check_joint_names(self.description, given, field="start")
        for name, value in given.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(float(value)):
                raise InvalidRequest(f"{value!r} is not a finite number [rad]",
                                     field=f"start.{name}")
            start[self.joint_names.index(name)] = float(value)
        check_positions(self.joint_names, start, np.column_stack([self._lower, self._upper]),
                        field="start")
        return start

    # -- time and verify --------------------------------------------------------------
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
        # the carried objects' masses enter the timing and the verifier alike
        dynamics, profiles = self.payload(world.attached)
        timer = profiles[profile]
        verifier = Verifier(limits, dynamics, world,
                            clearance_states=self.clearance_states)
        proofs = _CurveProofs(world, certificate)
        derating = Derating()
        t_param = t_verify = 0.0
        report: VerificationReport | None = None
        for attempt in range(1, MAX_ATTEMPTS + 1):
            t_a = time.perf_counter()
            timing = timer.parameterise(curve, path,
                                        ActiveLimits.from_limits(limits, derating))
            traj = JointTrajectory.sample(timing, dynamics.torques_batch,
                                          joint_names=self.joint_names,
                                          sample_rate=sample_rate, profile=profile,
                                          max_samples=max_samples)
            t_b = time.perf_counter()
            report = verifier.verify(traj, enforce_jerk=timer.enforce_jerk,
                                     derating=derating, attempts=attempt,
                                     certificate=proofs(timing))
            t_c = time.perf_counter()
            t_param += t_b - t_a
            t_verify += t_c - t_b
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
