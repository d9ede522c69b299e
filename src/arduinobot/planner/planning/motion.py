"""What a motion request asks and what a solved motion is: the planner's value types.

Kept apart from :mod:`arduinobot.planner.planning.pipeline` so the strategies (from_rest,
moving_start) and the door over them share them without importing each other.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from arduinobot.planner.planning.goals import (
    JointGoal,
    LineGoal,
    NamedGoal,
    PoseGoal,
    PositionGoal,
    check_goal,
)
from arduinobot.planner.planning.lines.line_path import LineReport
from arduinobot.planner.planning.reached import Reached
from arduinobot.planner.timing.trajectory import JointTrajectory
from arduinobot.planner.timing.verify import VerificationReport
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle

Profile = Literal["jerk_limited", "time_optimal"]


@dataclass(frozen=True)
class MotionRequest:
    """A motion to plan. Joint values [rad]; ``start`` missing = every actuated joint at 0.

    ``group``: any SRDF group or ``all``; None plans for a named goal's own group, else
    the description's default group. ``velocity_scaling``/``acceleration_scaling`` in
    [0.01, 1] multiply the full limits (MoveIt's semantics); None takes the MoveIt
    config's ``default_*_scaling_factor`` (1 without one). Every number's range is in
    :data:`arduinobot.contract.ranges.RANGES`; ``profile`` names an entry of
    :data:`arduinobot.planner.timing.profiles.PROFILES`.
    """

    goal: JointGoal | NamedGoal | PositionGoal | PoseGoal | LineGoal
    start: Mapping[str, float] | None = None
    group: str | None = None
    obstacles: tuple[Obstacle, ...] = ()
    # objects the robot carries for this request (each posed in its link's frame)
    attached: tuple[AttachedObject, ...] = ()
    # point clouds' cells (the kept scene's), each one body: see arduinobot.scene.cloud
    clouds: tuple[CloudObstacle, ...] = ()
    planner: str = "RRTConnect"
    planning_time: float = 1.0          # [s], (0, 60]
    velocity_scaling: float | None = None       # [0.01, 1]
    acceleration_scaling: float | None = None   # [0.01, 1]
    profile: Profile = "jerk_limited"
    sample_rate: float = 100.0          # [Hz], [1, 1000]
    seed: int | None = None
    # the most samples the trajectory may have (duration x sample_rate + 2), refused
    # before sampling when it would: what a reply or a robot can take
    max_samples: int | None = None
    # a moving start [rad/s], [rad/s^2] by joint: see arduinobot.planner.planning.moving_start
    start_velocity: Mapping[str, float] | None = None
    start_acceleration: Mapping[str, float] | None = None
    # the plane the base stands on is an obstacle (arduinobot.scene.ground) unless False
    ground: bool = True
    # (object, obstacle) id pairs allowed to touch for this motion only: a carried object
    # and the support it rests on, until a lift clears it (a task's pick and place)
    allowed: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        check_goal(self.goal)


@dataclass(frozen=True)
class MotionResult:
    """A verified trajectory, the checked path it follows and how long each stage took.

    ``timing``: seconds per stage (validate, plan, simplify, recheck, parameterise,
    verify, total); ``path`` shape (k, dof) in ``trajectory.joint_names`` order.
    ``reached``: the tool frame at the end and the residuals to the goal (the planner
    fills it in for every strategy); ``line``: a straight-line move's report;
    ``lifted_off``: the (carried object, obstacle) pairs it was resting on at the start,
    allowed for this line (:mod:`arduinobot.planner.planning.resting`).
    """

    trajectory: JointTrajectory
    path: np.ndarray
    timing: Mapping[str, float]
    verification: VerificationReport
    planner: str
    reached: Reached | None = None
    line: LineReport | None = None
    lifted_off: tuple[tuple[str, str], ...] = ()
