"""One OMPL search over a group's joints (OMPL's SimpleSetup), and OMPL's process-wide
settings: which planners this build offers, how much it logs, its seeds.

The search sees the group's joints only (a RealVectorStateSpace within their position
limits); the others keep the start's values (:class:`StateCodec`). States and motions
are judged by the caller's world and edge check, so the same search runs with room
(:mod:`.room`) or without.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import numpy as np
import ompl.base as ob
import ompl.geometric as og
import ompl.util as ou

from arduinobot.contract.errors import InvalidRequest, NoPathFound
from arduinobot.planner.collision.proof.motion_check import (
    MotionChecker,
    StateChecker,
    StateCodec,
    ValidityChecker,
)

__all__ = ["MAX_SEED", "OmplLogLevel", "PLANNERS", "available_planners", "check_seed", "search",
           "set_ompl_log_level"]

PLANNERS = ("RRTConnect", "RRT", "RRTstar", "PRM", "PRMstar", "BITstar", "KPIECE1",
            "LBKPIECE1", "BKPIECE1", "EST", "FMT", "BFMT", "InformedRRTstar", "SORRTstar",
            "AORRTC")
# the largest seed a request may give (OMPL's seeds are 32-bit, as the wire schema's)
MAX_SEED = 2**32 - 1

OmplLogLevel = Literal["debug", "info", "warn", "error", "none"]


def check_seed(seed: object, field: str = "seed") -> None:
    """Raise :class:`InvalidRequest` naming ``field`` unless ``seed`` is None or an
    integer OMPL can take, in [0, MAX_SEED]."""
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)
                             or not 0 <= seed <= MAX_SEED):
        raise InvalidRequest(f"{seed!r} must be an integer in [0, {MAX_SEED}]", field=field)


def available_planners() -> tuple[str, ...]:
    """The planner names this OMPL build offers."""
    return tuple(p for p in PLANNERS if hasattr(og, p))


def set_ompl_log_level(level: OmplLogLevel) -> None:
    """How much OMPL writes to the console by itself (it logs past Python's logging).

    Process-wide, as OMPL has one log: applications call it once at start (the
    ``arduinobot`` command and the service's workers use "none" by default, as every
    failure reaches the caller as a :class:`PlanningError`; "info" with -v). OMPL
    reports a reseed after its first plan as an *error* ("Random number generation
    already started"), although every planner and sampler created after the reseed
    does draw from the new seed: that line is noise.
    """
    levels = {"debug": ou.LogLevel.LOG_DEBUG, "info": ou.LogLevel.LOG_INFO,
              "warn": ou.LogLevel.LOG_WARN, "error": ou.LogLevel.LOG_ERROR,
              "none": ou.LogLevel.LOG_NONE}
    if level not in levels:
        raise InvalidRequest(f"'{level}' is not one of {', '.join(levels)}", field="level")
    ou.setLogLevel(levels[level])


def search(states: StateChecker, edge_free: Callable[[np.ndarray, np.ndarray], bool],
           start: np.ndarray, goals: np.ndarray, columns: np.ndarray, limits: np.ndarray, *,
           planner: str, seed: int | None, budget: float, planning_time: float
           ) -> np.ndarray:
    """A path (shape (k, dof), full joint vectors) from ``start`` (dof,) to one of
    ``goals`` (g, dof) found by OMPL's ``planner`` within ``budget`` [s], moving only the
    joints ``columns`` (indices, shape (n,)) within ``limits`` (dof, 2) [rad]; states
    judged by ``states``, motions by ``edge_free``. ``planning_time`` [s]: the request's,
    for the error.

    Raises:
        NoPathFound: no exact solution within the budget (an approximate one is not a
            path).
    """
    if seed is not None:
        # OMPL ignores a seed of 0 (its generator goes on, unseeded): 0 seeds with the
        # one value past MAX_SEED, which no request can name
        ou.RNG.setSeed(int(seed) or MAX_SEED + 1)
    space = ob.RealVectorStateSpace(len(columns))
    bounds = ob.RealVectorBounds(len(columns))
    for i, j in enumerate(columns):
        bounds.setLow(i, float(limits[j, 0]))
        bounds.setHigh(i, float(limits[j, 1]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)
    si = ss.getSpaceInformation()
    codec = StateCodec(columns, start)
    svc = ValidityChecker(si, states, codec)
    mv = MotionChecker(si, edge_free, codec)
    ss.setStateValidityChecker(svc)
    si.setMotionValidator(mv)
    s = si.allocState()
    codec.put(start, s)
    ss.setStartState(s)
    gs = ob.GoalStates(si)
    for g in goals:
        st = si.allocState()
        codec.put(g, st)
        gs.addState(st)
    ss.setGoal(gs)
    ss.setPlanner(getattr(og, planner)(si))
    ss.setup()
    status = ss.solve(budget)
    if not ss.haveExactSolutionPath():
        raise NoPathFound(f"{planner} found no path in {planning_time:g} s ({status})",
                          details={"planner": planner, "planning_time": planning_time})
    p = ss.getSolutionPath()
    out = np.array([codec.full(p.getState(i)) for i in range(p.getStateCount())])
    # keep the svc/mv alive until OMPL is done with them
    del svc, mv
    return out
