"""The one door into planning: :class:`MotionPlanner` hands each request to a strategy.

What the service, the viewer, the benches and users call. It owns one
:class:`~arduinobot.planner.planning.context.PlanningContext` (the robot's worlds, limits, dynamics
and timing profiles, built once) and an ordered tuple of strategies
(:mod:`arduinobot.planner.planning.strategy`): the first that accepts a request solves it, calling
down into the context and into the strategies it wraps, never back into this class.

The strategies by default (:func:`default_strategies`): :class:`FromRest` (a
collision-free path, blended, timed, verified), :class:`StraightLine` (a tcp line, Pilz's
LIN) and :class:`FromMovingState` around the first (a moving start blended into that
plan). Every result carries what its last state reached (:mod:`arduinobot.planner.planning.reached`).
A carried object that starts resting on something is lifted off by a line only
(:mod:`arduinobot.planner.planning.resting`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.planner.cache import ArtifactCache
from arduinobot.planner.collision.proof.certificate import Certificate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.dynamics import InverseDynamics
from arduinobot.planner.kinematics.limits import JointLimits
from arduinobot.planner.planning.context import MAX_ATTEMPTS, PlanningContext
from arduinobot.planner.planning.from_rest import FromRest
from arduinobot.planner.planning.goal_states import resolve_group
from arduinobot.planner.planning.goals import LineGoal
from arduinobot.planner.planning.lines.straight_line import StraightLine, line_target
from arduinobot.planner.planning.motion import MotionRequest, MotionResult, Profile
from arduinobot.planner.planning.moving_start import FromMovingState
from arduinobot.planner.planning.reached import Reached, reached
from arduinobot.planner.planning.resting import lift_off
from arduinobot.planner.planning.strategy import Strategy, moves_at_start
from arduinobot.planner.timing.curve import Curve
from arduinobot.planner.timing.trajectory import JointTrajectory
from arduinobot.planner.timing.verify import VerificationReport
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle

__all__ = ["MotionPlanner", "MotionRequest", "MotionResult", "MAX_ATTEMPTS",
           "default_strategies"]


def default_strategies() -> tuple[Strategy, ...]:
    """From rest, a straight line from rest, and from a moving state into the plan
    from rest."""
    from_rest = FromRest()
    return (from_rest, StraightLine(), FromMovingState(from_rest))


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
        strategies: the ways of solving, tried in order (:func:`default_strategies`).
    """

    def __init__(self, description: Description, *, padding: float = 0.0,
                 max_worlds: int = 8, clearance_states: int = 1,
                 cache: ArtifactCache | None = None,
                 strategies: Sequence[Strategy] | None = None) -> None:
        self.context = PlanningContext(description, padding=padding, max_worlds=max_worlds,
                                       clearance_states=clearance_states, cache=cache)
        self.strategies: tuple[Strategy, ...] = (
            default_strategies() if strategies is None else tuple(strategies))

    def strategy(self, request: MotionRequest) -> Strategy:
        """The first strategy that accepts ``request``.

        Raises:
            InvalidRequest: (field ``goal``) none does.
        """
        for s in self.strategies:
            if s.accepts(request):
                return s
        start = "a moving start" if moves_at_start(request) else "rest"
        raise InvalidRequest(f"no strategy plans a {type(request.goal).__name__} from "
                             f"{start} (strategies: "
                             f"{', '.join(s.name for s in self.strategies)})", field="goal")

    def solve(self, request: MotionRequest) -> MotionResult:
        """Plan, time and verify a motion with the strategy that accepts it.

        Raises:
            InvalidRequest, JointLimitViolation, StartInCollision, GoalInCollision,
            GoalOutOfReach, NoPathFound: from validation and path planning.
            TrajectoryError: no timing passed verification (details hold the report).

        A carried object resting on something at the start (touching it) is lifted off
        by a straight line only, proven never to press into it; any other goal from
        there is refused with a hint (:mod:`arduinobot.planner.planning.resting`).
        """
        lift = lift_off(self.context, request)
        if lift is not None:
            request = lift.request
        result = self.strategy(request).solve(self.context, request)
        if lift is not None:
            lift.check_end(self.context, result)
            result = replace(result, lifted_off=lift.pairs)
        if result.reached is None:
            result = replace(result, reached=self._reached(request, result))
        return result

    def _reached(self, request: MotionRequest, result: MotionResult) -> Reached:
        # what the last state reaches against the goal: every strategy's reply has it
        goal = request.goal
        group = resolve_group(self.description, request.group, goal)
        target = None
        if isinstance(goal, LineGoal) and result.line is not None:
            target = np.asarray(result.line.end)
        elif isinstance(goal, LineGoal):
            target = line_target(goal, *self._tool(result.trajectory.positions[0]))
        return reached(self.description, self.context.kin, goal,
                       np.asarray(result.trajectory.positions[-1], float), group=group,
                       target=target)

    def _tool(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tcp = self.description.tcp
        assert tcp is not None  # only for a line goal, which planned only with a tcp
        t = self.context.kin.link_pose(q, tcp.parent_link)
        return (t[:3, :3] @ np.asarray(tcp.xyz, float) + t[:3, 3],
                t[:3, :3] @ tcp.rotation())

    # -- the context's resources and stages, for callers that time paths themselves ---
    @property
    def description(self) -> Description:
        return self.context.description

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The actuated joints, in the order of every vector and trajectory column."""
        return self.context.joint_names

    @property
    def dynamics(self) -> InverseDynamics:
        return self.context.dynamics

    def world(self, obstacles: tuple[Obstacle, ...],
              attached: tuple[AttachedObject, ...] = (),
              clouds: tuple[CloudObstacle, ...] = (), *,
              ground: bool = True,
              allowed: tuple[tuple[str, str], ...] = ()) -> CollisionWorld:
        """The collision world for ``obstacles`` (with the ``attached`` objects carried,
        the ``clouds``' cells and the ground unless ``ground`` is false; the (object,
        obstacle) pairs ``allowed`` not checked), built once per distinct set."""
        return self.context.world(obstacles, attached, clouds, ground=ground,
                                  allowed=allowed)

    def limits(self, velocity_scaling: float, acceleration_scaling: float) -> JointLimits:
        """The joint limits scaled by the two factors, built once per pair."""
        return self.context.limits(velocity_scaling, acceleration_scaling)

    def scaling(self, request: MotionRequest) -> tuple[float, float]:
        """The request's (velocity, acceleration) scaling, or the MoveIt config's defaults."""
        return self.context.scaling(request)

    def validate(self, request: MotionRequest) -> np.ndarray:
        """Check every field; the start vector [rad], shape (dof,)."""
        return self.context.validate(request)

    def time_path(self, curve: Curve, path: np.ndarray, world: CollisionWorld,
                  limits: JointLimits, *, profile: Profile = "jerk_limited",
                  sample_rate: float = 100.0, certificate: Certificate | None = None,
                  max_samples: int | None = None
                  ) -> tuple[JointTrajectory, VerificationReport, float, float]:
        """:meth:`PlanningContext.time_path`: time ``curve``, verify, derate until it
        passes; the trajectory, its report and the seconds spent timing and verifying."""
        return self.context.time_path(curve, path, world, limits, profile=profile,
                                      sample_rate=sample_rate, certificate=certificate,
                                      max_samples=max_samples)
