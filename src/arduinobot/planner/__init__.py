"""The arduinobot motion planner: one place to import it from.

    from arduinobot.planner import MotionPlanner, MotionRequest, JointGoal, Obstacle, PlanningError

The errors, codes and ranges are imported with the package (they need nothing but the
standard library); every other name is imported on first use (PEP 562), so importing
``planner`` for its errors, codes or ranges (the client does) does not load OMPL, FCL,
numba or toppra.

- ``kinematics/``: forward kinematics, inverse dynamics, IK, the joint limits.
- ``collision/``: the collision world and the proof that a motion is free.
- ``timing/``: from a path to a timed, verified trajectory.
- ``planning/``: goals, OMPL search, the strategies and the one door (``MotionPlanner``).
- ``tasks/``: ordered steps planned as a whole.
- ``checks``: the request checks every layer shares (joint names, position limits).
- ``path_limits``: the limits a time parameterisation works to, torque along a curve.
- ``cache``: artifacts kept between runs, keyed by the content they came from.
- ``frames``: the robot's link poses and contacts for the scene's attach and detach
  (:class:`~arduinobot.scene.frames.Frames` on the planner's kinematics and bodies).
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

from arduinobot.contract.codes import Code
from arduinobot.contract.errors import (
    GoalInCollision,
    GoalOutOfReach,
    InvalidRequest,
    JointLimitViolation,
    LimitsError,
    NoPathFound,
    PlanningError,
    ShuttingDown,
    StartInCollision,
    StateInCollision,
    TrajectoryError,
)
from arduinobot.contract.ranges import RANGES, Range, check_range

if TYPE_CHECKING:  # what the lazy names are, for type checkers and editors
    from arduinobot.planner.planning.context import PlanningContext
    from arduinobot.planner.planning.from_rest import FromRest
    from arduinobot.planner.planning.goals import JointGoal, NamedGoal, PositionGoal
    from arduinobot.planner.planning.motion import MotionRequest, MotionResult, Profile
    from arduinobot.planner.planning.moving_start import FromMovingState
    from arduinobot.planner.planning.pipeline import MotionPlanner, default_strategies
    from arduinobot.planner.planning.strategy import Strategy
    from arduinobot.planner.timing.profiles import PROFILES, TimingProfile
    from arduinobot.planner.timing.trajectory import JointTrajectory
    from arduinobot.planner.timing.verify import VerificationReport
    from arduinobot.scene.obstacles import Obstacle

logging.getLogger(__name__).addHandler(logging.NullHandler())

# each lazily imported name -> the module (relative to this package) that defines it
_LAZY: dict[str, str] = {
    "MotionPlanner": ".planning.pipeline",
    "default_strategies": ".planning.pipeline",
    "MotionRequest": ".planning.motion",
    "MotionResult": ".planning.motion",
    "Profile": ".planning.motion",
    "JointGoal": ".planning.goals",
    "NamedGoal": ".planning.goals",
    "PositionGoal": ".planning.goals",
    "Strategy": ".planning.strategy",
    "FromRest": ".planning.from_rest",
    "FromMovingState": ".planning.moving_start",
    "PlanningContext": ".planning.context",
    "Obstacle": "arduinobot.scene.obstacles",
    "PROFILES": ".timing.profiles",
    "TimingProfile": ".timing.profiles",
    "JointTrajectory": ".timing.trajectory",
    "VerificationReport": ".timing.verify",
}

__all__ = [
    # the door, its request and result, the goals and the scene
    "MotionPlanner", "MotionRequest", "MotionResult", "Profile", "JointGoal", "NamedGoal",
    "PositionGoal", "Obstacle", "JointTrajectory", "VerificationReport",
    # for a new way of solving or of timing
    "Strategy", "FromRest", "FromMovingState", "PlanningContext", "default_strategies",
    "TimingProfile", "PROFILES",
    # ranges, codes and every error
    "RANGES", "Range", "check_range", "Code", "PlanningError", "InvalidRequest",
    "JointLimitViolation", "StateInCollision", "StartInCollision", "GoalInCollision",
    "GoalOutOfReach", "NoPathFound", "TrajectoryError", "LimitsError", "ShuttingDown",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value  # imported once: later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
