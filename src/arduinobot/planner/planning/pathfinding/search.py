"""One OMPL search over a group's joints (OMPL's SimpleSetup), and OMPL's process-wide
settings: which planners this build offers, how much it logs, its seeds.

The search sees the group's joints only (a RealVectorStateSpace within their position
limits); the others keep the start's values (:class:`StateCodec`). States and motions
are judged by the caller's world and edge check, so the same search runs with room
(:mod:`.room`) or without.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
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

__all__ = ["FALLBACK", "FIRST_SLICE", "Found", "Track", "MAX_SEED", "RANGE", "SLICED", "OmplLogLevel", "PLANNERS", "available_planners", "check_seed", "search",
           "set_ompl_log_level"]

PLANNERS = ("RRTConnect", "RRT", "RRTstar", "PRM", "PRMstar", "BITstar", "KPIECE1",
            "LBKPIECE1", "BKPIECE1", "EST", "FMT", "BFMT", "InformedRRTstar", "SORRTstar",
            "AORRTC")
# the largest seed a request may give (OMPL's seeds are 32-bit, as the wire schema's)
MAX_SEED = 2**32 - 1

# the planners whose budget is sliced (:func:`search`): they evaluate their termination
# condition in the calling thread (a Python one asked from PRM's roadmap thread would
# wait for the GIL forever); another planner gets the whole budget in one solve
SLICED = frozenset({"RRTConnect", "RRT", "KPIECE1", "BKPIECE1", "LBKPIECE1"})
# the planner that takes turns with the asked one (:func:`search`)
FALLBACK = "BKPIECE1"
# the fallback's slices, in iterations, as a share of the asked planner's (a BKPIECE1
# iteration costs ~5 RRTConnect ones on the Panda in MotionBenchMaker's cage: 2.3 vs
# 0.45 ms). State checks to a path on the Panda's 3 cage problems and the tall
# bookshelf's slot, 20 s budgets, by share: 0.1 109k, 0.2 114k, 0.4 76k, 0.6 79k, 1.0 86k
FALLBACK_SHARE = 0.4
# planner iterations of the first slice (:func:`search`)
FIRST_SLICE = 500
# [rad] the longest edge a tree grows by (:func:`search`)
RANGE = 0.5

_log = logging.getLogger(__name__)

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


@dataclass(frozen=True)
class Track:
    """One world a search runs in: how its states and motions are judged, and its ends.

    Attributes:
        states: judges a state (a full joint vector).
        edge_free: judges the straight motion between two full joint vectors.
        start: shape (dof,), the full joint vector the trees grow from.
        goals: shape (g, dof), the full joint vectors the goal tree grows from.
        turns: at most this many slices in this world, all planners together (None:
            until the budget ends).
    """

    states: StateChecker
    edge_free: Callable[[np.ndarray, np.ndarray], bool]
    start: np.ndarray
    goals: np.ndarray
    turns: int | None = None


@dataclass(frozen=True)
class Found:
    """A search's path and who found it.

    Attributes:
        path: shape (k, dof), full joint vectors, first = start, last = a goal.
        planner: the OMPL planner whose tree reached the goal.
        rounds: the slices run, all planners and tracks together (1: the first).
        track: the index of the :class:`Track` the path was found in.
    """

    path: np.ndarray
    planner: str
    rounds: int
    track: int = 0


def search(tracks: Sequence[Track], columns: np.ndarray, limits: np.ndarray, *,
           planner: str, seed: int | None, budget: float, planning_time: float,
           fallback: str | None = FALLBACK, first_slice: int = FIRST_SLICE,
           range_: float = RANGE) -> Found:
    """A path from a track's start to one of its goals found within ``budget`` [s],
    moving only the joints ``columns`` (indices, shape (n,)) within ``limits`` (dof, 2)
    [rad]; each :class:`Track` judges its own states and motions. ``planning_time`` [s]:
    the request's, for the error.

    The budget is spent in slices of planner iterations, ``planner`` and ``fallback``
    (another family: a tree that grows by cells of free space, where RRTConnect's two
    trees keep meeting the same shelf) taking turns, each slice twice the iterations of
    the round before (``first_slice`` for the first, ``FALLBACK_SHARE`` of it for the
    fallback's, whose iterations cost more), when ``planner`` is one of ``SLICED``
    (else it alone gets the whole budget); within a planner's turn every track with
    turns left runs its slice, in the order given (a world with room first, then the
    exact one: where the room closes every passage, the exact world's first slice comes
    before the roomy world's second planner, not after it). Each planner keeps its tree
    in each track between its slices, so a turn costs no work already done. Slices are
    counted in iterations, not seconds, so a seeded search repeats itself wherever it
    ends (as long as the budget does not cut it short). ``range_`` [rad]: the longest
    edge a tree grows by (OMPL's default, a fifth of the space's diagonal, is ~2.7 rad
    on a 7-joint arm: long edges that clutter refuses; measured in docs/bench.md).

    Raises:
        NoPathFound: no exact solution within the budget, or every track's turns spent
            (an approximate solution is not a path).
    """
    if not tracks:
        raise ValueError("a search needs a track")
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
    codecs = [StateCodec(columns, t.start) for t in tracks]
    sliced = planner in SLICED
    names = [planner] + ([fallback] if sliced and fallback not in (None, planner) else [])
    # per (track, planner): its SimpleSetup and the checkers it holds (kept alive with it)
    setups: dict[tuple[int, str], tuple[og.SimpleSetup, object, object]] = {}
    used = [0] * len(tracks)
    deadline = time.perf_counter() + budget
    rounds, size = 0, first_slice

    def give_up() -> NoPathFound:
        return NoPathFound(f"{' and '.join(names)} found no path in {planning_time:g} s",
                           details={"planner": planner, "planning_time": planning_time,
                                    "rounds": rounds, "planners": names})
    while True:
        for name in names:
            for k, track in enumerate(tracks):
                if track.turns is not None and used[k] >= track.turns:
                    continue
                left = deadline - time.perf_counter()
                if left <= 0:
                    raise give_up()
                if (k, name) not in setups:
                    setups[(k, name)] = _built(space, codecs[k], track, name, range_)
                ss = setups[(k, name)][0]
                rounds += 1
                used[k] += 1
                t0 = time.perf_counter()
                if sliced:
                    ss.solve(_slice(size if name == planner
                                    else max(1, int(size * FALLBACK_SHARE)), left))
                else:
                    ss.solve(left)
                _log.debug("slice %d: %s in track %d, %d iterations, %.3f s", rounds, name,
                           k, size, time.perf_counter() - t0)
                if ss.haveExactSolutionPath():
                    p = ss.getSolutionPath()
                    out = np.array([codecs[k].full(p.getState(i))
                                    for i in range(p.getStateCount())])
                    return Found(out, name, rounds, k)
        if all(t.turns is not None and u >= t.turns for t, u in zip(tracks, used)):
            raise give_up()
        size *= 2


def _slice(iterations: int, seconds: float) -> ob.PlannerTerminationCondition:
    # ends after ``iterations`` evaluations (a planner asks once per iteration) or
    # ``seconds`` [s], whichever first
    end = time.perf_counter() + seconds
    count = [0]

    def done() -> bool:
        count[0] += 1
        return count[0] > iterations or time.perf_counter() >= end
    return ob.PlannerTerminationCondition(done)


def _built(space: ob.StateSpace, codec: StateCodec, track: Track, name: str,
           range_: float) -> tuple[og.SimpleSetup, object, object]:
    ss = og.SimpleSetup(space)
    si = ss.getSpaceInformation()
    svc = ValidityChecker(si, track.states, codec)
    mv = MotionChecker(si, track.edge_free, codec)
    ss.setStateValidityChecker(svc)
    si.setMotionValidator(mv)
    s = si.allocState()
    codec.put(track.start, s)
    ss.setStartState(s)
    gs = ob.GoalStates(si)
    for g in track.goals:
        st = si.allocState()
        codec.put(g, st)
        gs.addState(st)
    ss.setGoal(gs)
    pl = getattr(og, name)(si)
    if hasattr(pl, "setRange"):
        pl.setRange(range_)
    ss.setPlanner(pl)
    ss.setup()
    return ss, svc, mv
