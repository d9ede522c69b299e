"""Planning from rest: a collision-free path with OMPL, blended, timed, verified.

The strategy for every goal of :mod:`arduinobot.planner.planning.goals` (joint values, a named
state, a tcp position) from a start at rest: the path planner finds a certified path
(a straight line when it is free), :func:`~arduinobot.planner.timing.curve.build_curve` blends its
corners (each blend certified as it is made), and the context times and verifies it.
"""

from __future__ import annotations

import time

import numpy as np

from arduinobot.planner.collision.proof.certificate import combine
from arduinobot.planner.planning.context import PlanningContext
from arduinobot.planner.planning.goals import JointGoal, NamedGoal, PoseGoal, PositionGoal
from arduinobot.planner.planning.motion import MotionRequest, MotionResult
from arduinobot.planner.planning.pathfinding.paths import PathRequest
from arduinobot.planner.planning.strategy import moves_at_start
from arduinobot.planner.timing.curve import build_curve

__all__ = ["FromRest"]


class FromRest:
    """Free-space motion from a start at rest to a joint, named, position or pose goal."""

    name = "from rest"

    def accepts(self, request: MotionRequest) -> bool:
        return not moves_at_start(request) and \
            isinstance(request.goal, (JointGoal, NamedGoal, PositionGoal, PoseGoal))

    def solve(self, context: PlanningContext, request: MotionRequest) -> MotionResult:
        """Plan, time and verify ``request`` from rest.

        Raises:
            InvalidRequest, JointLimitViolation, StartInCollision, GoalInCollision,
            GoalOutOfReach, NoPathFound: from validation and path planning.
            TrajectoryError: no timing passed verification (details hold the report).
        """
        t0 = time.perf_counter()
        start = context.validate(request)
        world, paths = context.scene(request.obstacles, request.attached, request.clouds,
                                     ground=request.ground,
                                     allowed=request.allowed)
        t1 = time.perf_counter()
        res = paths.solve(PathRequest(start=start, goal=request.goal, group=request.group,
                                      planner=request.planner,
                                      planning_time=request.planning_time, seed=request.seed),
                          blend=True)
        t2 = time.perf_counter()
        if res.curve is not None:
            # the blends were proven with the path, in one walk
            curve, proof = res.curve, res.certificate
        else:
            # blends certified as they are made; with the path's proof, that certifies
            # the whole curve: its straight parts lie on the path's proven segments
            curve = build_curve(res.path, paths.proof)
            proof = combine([res.certificate, *(c.certificate for c in curve.corners
                                                if c.certificate is not None)]) \
                if res.certificate else None
        t3 = time.perf_counter()
        lim = context.limits(*context.scaling(request))
        traj, report, t_param, t_verify = context.time_path(
            curve, res.path, world, lim, profile=request.profile,
            sample_rate=request.sample_rate, certificate=proof,
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
