"""The registry of timing profiles: how a blended path gets its times.

A request names its profile (``MotionRequest.profile``); the planner looks it up here
instead of branching on the name, so a new profile is one class and one entry in
:data:`PROFILES`, and every place that needs to know a profile's nature (the verifier's
jerk check, the schema's enum, the request check) reads it from the registry.
``tests/planner/planning/test_pipeline.py`` holds :data:`PROFILES` equal to
:data:`arduinobot.planner.planning.motion.Profile` and to the plan request schema's enum.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Protocol

import numpy as np

from arduinobot.planner.path_limits import ActiveLimits, BatchDynamics
from arduinobot.planner.timing.curve import Curve, build_curve
from arduinobot.planner.timing.ruckig_timing import JerkLimitedTiming
from arduinobot.planner.timing.toppra_timing import TimeOptimalTiming
from arduinobot.planner.timing.trajectory import CurveTiming

__all__ = ["TimingProfile", "JerkLimited", "TimeOptimal", "PROFILES", "build_profiles"]


class TimingProfile(Protocol):
    """One way of timing a blended path under the active limits.

    ``name``: its key in :data:`PROFILES` (and on the wire). ``enforce_jerk``: whether the
    verifier holds its trajectories to the jerk limits (a profile that does not limit
    jerk, like toppra's piecewise-constant acceleration, is not checked for it).
    """

    name: str
    enforce_jerk: bool

    def prepare(self, limits: ActiveLimits) -> None:
        """Build now what is slow to build for ``limits`` (not on the first request)."""
        ...

    def parameterise(self, curve: Curve, path: np.ndarray, limits: ActiveLimits
                     ) -> CurveTiming:
        """Time ``curve``, blended from ``path`` (shape (k, dof)), within ``limits``.

        Raises:
            TrajectoryError: no timing within the limits.
        """
        ...


class JerkLimited:
    """ruckig along each curve piece: jerk-limited, every piece's bounds conservative."""

    name = "jerk_limited"
    enforce_jerk = True

    def __init__(self, dynamics: BatchDynamics) -> None:
        self.timing = JerkLimitedTiming(dynamics)

    def prepare(self, limits: ActiveLimits) -> None:
        """Nothing to build: ruckig's generator is made with the timing."""

    def parameterise(self, curve: Curve, path: np.ndarray, limits: ActiveLimits
                     ) -> CurveTiming:
        timing = self.timing.parameterise(curve, limits)
        if any(c.kind == "blend" for c in curve.corners):
            # conservative per-piece bounds can make a sharp blend slower than stopping
            # at the corner on straight, re-checked edges: keep the faster. Timing the
            # stops (inverse dynamics along every edge) is needed only where its floor
            # leaves it a chance (the margin: far above ruckig's rounding)
            edges = build_curve(path, None, max_radius=0.0)
            if self.timing.rest_to_rest_floor(edges, limits) * (1 - 1e-9) < timing.duration:
                stops = self.timing.parameterise(edges, limits)
                if stops.duration < timing.duration:
                    return stops
        return timing


class TimeOptimal:
    """toppra: time-optimal under velocity, acceleration and effort, jerk unlimited."""

    name = "time_optimal"
    enforce_jerk = False

    def __init__(self, dynamics: BatchDynamics) -> None:
        self.timing = TimeOptimalTiming(dynamics)

    def prepare(self, limits: ActiveLimits) -> None:
        """toppra's constraint objects are slow to build: build them for ``limits``."""
        self.timing.constraints(limits)

    def parameterise(self, curve: Curve, path: np.ndarray, limits: ActiveLimits
                     ) -> CurveTiming:
        return self.timing.parameterise(curve, limits)


#: Every timing profile by name, each built from the robot's inverse dynamics.
PROFILES: Mapping[str, Callable[[BatchDynamics], TimingProfile]] = {
    JerkLimited.name: JerkLimited,
    TimeOptimal.name: TimeOptimal,
}


def build_profiles(dynamics: BatchDynamics) -> dict[str, TimingProfile]:
    """One instance of every registered profile for a robot's ``dynamics``."""
    return {name: make(dynamics) for name, make in PROFILES.items()}
