"""Joint-space path planning with OMPL: build, validate, solve.

A request names a group (any SRDF group, or ``all``); joints outside it keep their
start values. Solving validates start and goal (limits, collisions), tries the straight
line, runs the chosen OMPL planner, shortcuts the path and re-checks it densely, so a
returned path never grazes anything between checks.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from arduinobot.contract.errors import InvalidRequest, NoPathFound, StartInCollision
from arduinobot.description import Description
from arduinobot.planner.collision.proof.certificate import Certificate
from arduinobot.planner.collision.proof.certify import MAX_BOUNDS, Certifier
from arduinobot.planner.collision.proof.ladder import MAX_EXACT, MAX_NEAR
from arduinobot.planner.collision.proof.motion_check import motion_valid, sampled_motion_valid
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goal_states import check_limits, resolve_goal, resolve_group
from arduinobot.planner.planning.goals import Goal, check_goal
from arduinobot.planner.planning.pathfinding.blended import prove_blended
from arduinobot.planner.planning.pathfinding.room import (
    Guarded,
    StateChecker,
    escape,
    roomy_world,
    short_of_room,
)
from arduinobot.planner.planning.pathfinding.search import (
    Found,
    Track,
    available_planners,
    check_seed,
    search,
)
from arduinobot.planner.planning.pathfinding.shortcut import shortcut_path
from arduinobot.planner.timing.curve import Curve

_log = logging.getLogger(__name__)

__all__ = ["FINEST_STEP", "PLAN_STEP", "PROOF_BOUNDS", "PROOF_EXACT", "PROOF_NEAR", "PROOF_REPLANS", "ROOM",
           "ROOMY_ROUNDS", "PathPlanner", "PathRequest", "PathResult"]

# edges (a, b), by their bytes, whose proof failed in a request's earlier attempts
Refused = frozenset[tuple[bytes, bytes]]

# [rad] edges are checked at states this far apart while searching and shortcutting; the
# path found is then certified over its whole length (and re-planned with finer samples,
# then certified edges, in the rare case it grazes between samples)
PLAN_STEP = 0.02
# [m] detours are first searched and shortcut with every moving pair kept this much
# farther apart than the clearance, as far as the OBB trees alone can prove (no FCL):
# paths that do not hug the robot or the scene are proven with long certification steps
# instead of thousands of exact distances, and leave the servos room to track. Where no
# such path exists (ends or passages closer than this), the search runs without it.
ROOM = 0.002
# the found path's proof budgets (:class:`.certify.Certifier`): exact queries (0.3-4 ms
# each on CAD meshes) and walk stops (hull queries, ~20-50 us). Spent, the path is
# refused at the edge where it was and planned again without it. The certifier's own
# (4000, 40000) let a proof along a shelf 0.4 mm away run 19 s.
PROOF_EXACT = 100
PROOF_NEAR = 2000
# and its whole cost in tree bounds (:data:`.certify.MAX_BOUNDS`): ~0.45 s of CPU on the
# Panda. Its costliest proofs on MotionBenchMaker paths counted 10-13k, but a generated
# 7-joint arm of millimetre meshes in a cage counts 37k (679 walk stops; 0.2-0.25 s), and
# 20k refused that proof on every re-plan until the 10 s ran out (the slow test
# tests/service/test_seven_joint_clutter.py failed on it)
PROOF_BOUNDS = 100_000
# paths refused for a spent proof budget that are planned again at the same step (each
# without the edges refused so far); past that, as a graze: finer samples
PROOF_REPLANS = 2
# slices of the search (:func:`.search.search`) the roomy world gets: its first turn of
# each planner, ~0.3 s on the Panda in clutter, each followed by the exact world's turn of
# the same planner. Half the budget (before) starved the cage, whose passages are
# narrower than the room: 2 of 3 MotionBenchMaker cage problems failed in 5 s, solved in
# 1-3 s without room; both roomy turns before the exact world's first cost the cage ~0.2
# s a plan (in process, 21 x 3: wall median 126 -> 92 ms, p95 1.61 -> 1.19 s, solved
# 62 -> 63 of 63, when the exact world's first slice moved before the roomy BKPIECE1's)
ROOMY_ROUNDS = 2
# [rad] a path that grazes between its edges' samples is planned again with them twice
# as close, down to this step, and below it with certified edges
FINEST_STEP = 0.01


@dataclass(frozen=True)
class PathRequest:
    """A planning problem.

    Attributes:
        start: the full actuated joint vector [rad], shape (dof,).
        goal: joint values, a named SRDF state, or a tcp position.
        group: the joints that move; the others keep their start values.
        planner: an OMPL geometric planner's name.
        planning_time: the planner's time budget [s].
        seed: seeds OMPL's random generator, making results reproducible.
    """

    start: np.ndarray
    goal: Goal
    group: str | None = None  # None: the named state's group, else the default group
    planner: str = "RRTConnect"
    planning_time: float = 1.0
    seed: int | None = None

    def __post_init__(self) -> None:
        check_goal(self.goal)


@dataclass(frozen=True)
class PathResult:
    """A collision-free joint path.

    Attributes:
        joint_names: the order of the joint vectors.
        path: waypoints, shape (k, dof), k >= 2, first = start; every straight segment
            is certified free over its whole length (:mod:`arduinobot.planner.collision.proof.certify`).
        planner: the planner that produced it ("straight line" if none was needed).
        timings: seconds per stage: validate, straight_line, plan, simplify, recheck.
        checks: state validity checks made (narrow or broad phase).
        straight_line: the straight line to the goal was free.
        length: joint-space path length [rad] (sum of Euclidean segment lengths).
        certificate: the proof that every segment is free, with its certified clearance
            (:class:`arduinobot.planner.collision.proof.certificate.Certificate`); reused for anything that follows the
            segments, such as the straight parts of a blended curve.
        curve: when solved with ``blend``, the path's corners blended as
            :func:`arduinobot.planner.timing.curve.build_curve` would (default radii), every blend
            covered by ``certificate`` too; None: blend them yourself.
    """

    joint_names: tuple[str, ...]
    path: np.ndarray
    planner: str
    timings: Mapping[str, float] = field(default_factory=dict)
    checks: int = 0
    straight_line: bool = False
    length: float = 0.0
    certificate: Certificate | None = None
    curve: Curve | None = None


def _path_length(path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


class PathPlanner:
    """Plans paths in one collision world.

    Args:
        world: the collision world (robot, scene, padding) to plan in.
        description: the robot (groups and named states from its SRDF).
        step: the largest joint step [rad] when checking an edge while planning.
        certify_edges: accept only edges certified free over their whole length (else
            edges are sampled at ``step`` and the found path is certified afterwards).
        room: detours are searched first with this much room [m] (see ``ROOM``); 0 never.
        proof_budget: the found path's proof budgets, exact queries and walk stops (see
            ``PROOF_EXACT``); a planner of certified edges uses the certifier's own.
    """

    def __init__(self, world: CollisionWorld, description: Description, *,
                 step: float = PLAN_STEP, certify_edges: bool = False,
                 room: float = ROOM,
                 proof_budget: tuple[int, int] = (PROOF_EXACT, PROOF_NEAR)) -> None:
        self.world = world
        self.description = description
        self.step = step
        self.certify_edges = certify_edges
        self.room = room
        self._roomy: dict[tuple[str, ...], CollisionWorld] = {}
        self._guarded: dict[tuple[tuple[str, ...], tuple[tuple[str, str], ...]], Guarded] = {}
        self._fallback: PathPlanner | None = None
        self.certifier = Certifier(world)
        # the found path's proof also certifies a clearance worth reporting (fraction
        # 0.5), within a budget: a path that grazes a shelf for its whole length is
        # refused and planned again without that edge, in bounded time
        # (a planner of certified edges proves its path with the certifier's own budgets:
        # each edge was proven with them already)
        exact, near = (MAX_EXACT, MAX_NEAR) if certify_edges else proof_budget
        self.proof = Certifier(world, fraction=0.5, max_exact=exact, max_near=near,
                               max_bounds=MAX_BOUNDS if certify_edges else PROOF_BOUNDS)
        names = world.kin.joint_names
        self._groups: dict[str, tuple[str, ...]] = {
            g: tuple(j for j in joints if j in names)
            for g, joints in description.group_joints().items()}
        self._groups["all"] = tuple(names)
        self._limits = description.robot.position_limits(names)

    def group_joints(self, group: str) -> tuple[str, ...]:
        try:
            return self._groups[group]
        except KeyError:
            raise InvalidRequest(f"'{group}' is not a group ({', '.join(self._groups)})",
                                 field="group") from None

    def roomy(self, joints: tuple[str, ...]) -> CollisionWorld:
        """The world detours of ``joints`` are first searched in: every pair they move
        kept ``room`` farther apart, by the trees alone; pairs they do not move are left
        to the exact world (a gripper's fingers stay as close as they are)."""
        w = self._roomy.get(joints)
        if w is None:
            w = self._roomy[joints] = roomy_world(self.world, joints, self.room)
        return w

    def guarded(self, joints: tuple[str, ...], lost: tuple[tuple[str, str], ...]) -> Guarded:
        """The roomy world of ``joints`` where the pairs ``lost`` (by name) lose the room
        alone: checked at the plain clearance, every other pair keeping it
        (:mod:`.room`)."""
        g = self._guarded.get((joints, lost))
        if g is None:
            g = self._guarded[(joints, lost)] = Guarded.of(self.world, joints, lost,
                                                           self.room)
        return g

    def _edge_free(self, a: np.ndarray, b: np.ndarray, refused: Refused,
                   world: StateChecker | None = None) -> bool:
        if refused and (a.tobytes(), b.tobytes()) in refused:
            return False
        if world is not None:
            return sampled_motion_valid(world, a, b, self.step)
        if self.certify_edges:
            return motion_valid(self.certifier, a, b, self.step)
        return sampled_motion_valid(self.world, a, b, self.step)

    # -- validate ---------------------------------------------------------------------
    def _validate(self, req: PathRequest) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        if req.planner not in available_planners():
            raise InvalidRequest(f"unknown planner '{req.planner}' (available: "
                                 f"{', '.join(available_planners())})", field="planner")
        if not (np.isfinite(req.planning_time) and req.planning_time > 0):
            raise InvalidRequest(f"{req.planning_time!r} must be > 0 [s]", field="planning_time")
        check_seed(req.seed)
        group = resolve_group(self.description, req.group, req.goal)
        joints = self.group_joints(group)
        if not joints:
            raise InvalidRequest(f"group '{group}' has no actuated joint", field="group")
        start = np.asarray(req.start, dtype=float)
        names = self.world.kin.joint_names
        if start.shape != (len(names),) or not np.all(np.isfinite(start)):
            raise InvalidRequest(f"must be {len(names)} finite values ({', '.join(names)})",
                                 field="start")
        check_limits(self.world, start, field="start")
        chk = self.world.check(start)
        if not chk.valid:
            raise StartInCollision("the start state collides", pairs=chk.pairs,
                                   q=dict(zip(names, map(float, start))))
        goals = resolve_goal(req.goal, world=self.world, description=self.description,
                             start=start, group_joints=joints, group=group)
        return start, goals, joints

    # -- solve ------------------------------------------------------------------------
    def solve(self, request: PathRequest, *, blend: bool = False) -> PathResult:
        """Plan a path for ``request``; with ``blend``, also its corners blended and
        proven with it in one walk where that succeeds (``PathResult.curve``,
        :mod:`.blended`).

        Raises:
            InvalidRequest, JointLimitViolation: a malformed request.
            StartInCollision, GoalInCollision: with every colliding pair.
            GoalOutOfReach: no IK solution for a position goal.
            NoPathFound: no path within the time budget.
        """
        return self._solve(request, blend=blend, refused=frozenset(), replans=0)

    def _solve(self, request: PathRequest, *, blend: bool,
               refused: Refused, replans: int = 0) -> PathResult:
        # ``refused``: the edges whose proof failed in this request's earlier attempts,
        # refused without a check: an escape edge is drawn again exactly as it was (same
        # seed), and its finer samples pass again where it grazes between them (each
        # failed proof of a graze costs ~0.1-0.2 s on CAD meshes)
        timings: dict[str, float] = {}
        checks0 = self.world.checks
        t0 = time.perf_counter()
        start, goals, joints = self._validate(request)
        t1 = time.perf_counter()
        timings["validate"] = t1 - t0
        # Straight line first: nearest goal candidates first.
        order = np.argsort(np.linalg.norm(goals - start, axis=1))
        path = None
        for k in order:
            if self._edge_free(start, goals[k], refused):
                path = np.array([start, goals[k]])
                break
        t2 = time.perf_counter()
        timings["straight_line"] = t2 - t1
        straight = path is not None
        planner_name = "straight line"
        if path is None:
            path, room, planner_name = self._detour(request, start, goals, joints, refused)
        t3 = time.perf_counter()
        timings["plan"] = t3 - t2
        if not straight:
            # the straight lines to the goals collide (in the exact world, so with room
            # too): the first edge shortcutting would try
            path = shortcut_path(path, lambda a, b: self._edge_free(a, b, refused, room),
                                 seed=request.seed, blocked=[(start, g) for g in goals])
        t4 = time.perf_counter()
        timings["simplify"] = t4 - t3
        # every edge was checked at its samples as it was accepted: the proof alone
        curve = None
        if blend:
            cert, curve = prove_blended(self.proof, path, self.world, step=self.step)
        else:
            cert = self.proof.path(path, sample_step=None)
        t5 = time.perf_counter()
        timings["recheck"] = t5 - t4
        if not cert.free and not self.certify_edges:
            # an edge accepted on its samples grazes between them: plan again with edges
            # sampled twice as close, and where even that grazes, accepting only
            # certified edges (each edge a proof: several times slower; rare)
            # a spent budget (distance NaN) is no graze between samples: the same
            # planner again, without that edge, PROOF_REPLANS times
            spent = cert.failure is not None and np.isnan(cert.failure[3])
            retry = self if spent and replans < PROOF_REPLANS else self._retry()
            replans += spent
            _log.info("path not certified (%s); re-planning with %s", cert.failure,
                      "certified edges" if retry.certify_edges
                      else f"edges sampled {retry.step:g} rad apart")
            k = cert.failure[0] if cert.failure is not None else -1
            if 0 <= k < len(path) - 1:
                a, b = path[k], path[k + 1]
                refused = refused | {(a.tobytes(), b.tobytes()), (b.tobytes(), a.tobytes())}
            # the re-plan gets what is left of the budget: planning_time bounds the
            # whole request, however many paths its proofs refuse
            left = float(request.planning_time) - (time.perf_counter() - t0)
            if left <= 0:
                raise NoPathFound(
                    f"the path found was refused by its proof ({cert.failure}) and the "
                    f"{request.planning_time:g} s budget is spent",
                    details={"failure": str(cert.failure), "planner": planner_name,
                             "planning_time": request.planning_time})
            result = retry._solve(replace(request, planning_time=left), blend=blend,
                                  refused=refused, replans=replans)
            return PathResult(joint_names=result.joint_names, path=result.path,
                              planner=result.planner,
                              timings={k: timings.get(k, 0.0) + v
                                       for k, v in result.timings.items()},
                              checks=self.world.checks - checks0,
                              straight_line=result.straight_line, length=result.length,
                              certificate=result.certificate, curve=result.curve)
        if not cert.free:
            # cannot happen when every edge was certified; never return it
            raise NoPathFound("the path failed its certified re-check",
                              details={"failure": str(cert.failure), "planner": planner_name})
        return PathResult(joint_names=self.world.kin.joint_names, path=path,
                          planner=planner_name, timings=timings,
                          checks=self.world.checks - checks0, straight_line=straight,
                          length=_path_length(path), certificate=cert, curve=curve)

    def _retry(self) -> PathPlanner:
        # the planner a path that failed its proof is planned again with (kept: its
        # roomy worlds are built once)
        if self._fallback is None:
            finer = self.step / 2 >= FINEST_STEP - 1e-12
            self._fallback = PathPlanner(self.world, self.description,
                                         step=self.step / 2 if finer else self.step,
                                         certify_edges=not finer, room=self.room)
        return self._fallback

    def _detour(self, req: PathRequest, start: np.ndarray, goals: np.ndarray,
                joints: tuple[str, ...], refused: Refused
                ) -> tuple[np.ndarray, StateChecker | None, str]:
        # With room and without, taking turns (:func:`.search.search`): the roomy world
        # its first slice of each planner, the exact world each slice after the roomy
        # one's of the same planner, then every slice. An end that lacks the room
        # (a start a hair from the base) is joined by a short free edge to a nearby state
        # that has it, so only that edge comes close. Where no such edge leaves it (a
        # camera a millimetre from the turntable), the pairs short of room there lose
        # it alone (:mod:`.room`). Returns the path, the roomy world it was found in
        # (None: without room) and the planner that found it.
        budget = float(req.planning_time)
        if self.room > 0 and not self.certify_edges:
            roomy: StateChecker = self.roomy(joints)
            cols = np.array([self.world.kin.joint_names.index(j) for j in joints])
            rng = np.random.default_rng(req.seed)
            exact_edge = self._checker(refused, None)

            def leave(end: np.ndarray, toward: np.ndarray, roomy: StateChecker
                      ) -> np.ndarray | None:
                return escape(end, toward, cols, roomy, self._limits[cols], rng, exact_edge)
            head = leave(start, goals[0], roomy)
            tails = [(g, leave(g, start, roomy)) for g in goals]
            tails = [(g, e) for g, e in tails if e is not None]
            # an end stuck without room: the pairs exactly short of it there lose it
            # alone; if the trees still doubt others, those too
            for exact in (True, False):
                if head is not None and tails:
                    break
                stuck = ([start] if head is None else []) + ([] if tails else list(goals))
                lost = short_of_room(self.world, self.roomy(joints), stuck, self.room,
                                     exact=exact)
                if not lost:
                    continue
                roomy = self.guarded(joints, lost)
                _log.info("%d pairs lose the room alone: %s", len(lost), lost)
                head = leave(start, goals[0], roomy)
                tails = [(g, leave(g, start, roomy)) for g in goals]
                tails = [(g, e) for g, e in tails if e is not None]
            if head is not None and tails:
                ends = np.array([e for _, e in tails])
                found = self._search(req, [Track(roomy, self._checker(refused, roomy), head,
                                                 ends, turns=ROOMY_ROUNDS),
                                           self._track(start, goals, refused)],
                                     joints, budget)
                if found.track == 1:
                    _log.info("no detour with %.1f mm of room yet; found without",
                              1e3 * self.room)
                    return found.path, None, found.planner
                mid = found.path
                goal, end = min(tails, key=lambda t: float(np.abs(t[1] - mid[-1]).max()))
                # the escape edges, where an end needed one
                return np.vstack([[start]] * (head is not start) + [mid]
                                 + [[goal]] * (end is not goal)), roomy, found.planner
        found = self._search(req, [self._track(start, goals, refused)], joints, budget)
        return found.path, None, found.planner

    def _checker(self, refused: Refused, roomy: StateChecker | None
                 ) -> Callable[[np.ndarray, np.ndarray], bool]:
        return lambda a, b: self._edge_free(a, b, refused, roomy)

    def _track(self, start: np.ndarray, goals: np.ndarray, refused: Refused) -> Track:
        # the exact world's: no room, every turn the budget allows
        return Track(self.world, self._checker(refused, None), start, goals)

    def _search(self, req: PathRequest, tracks: list[Track], joints: tuple[str, ...],
                budget: float) -> Found:
        names = self.world.kin.joint_names
        return search(tracks, np.array([names.index(j) for j in joints], dtype=np.int64),
                      self._limits, planner=req.planner, seed=req.seed, budget=budget,
                      planning_time=req.planning_time)
