"""The collision world: the robot's link meshes, the objects it carries and the scene's
obstacles in python-fcl.

Built once per (description, obstacles, carried objects, padding) and reused for every check; the
robot's geometry (:mod:`.bodies`) is shared by every world of it. A check is fast FK
(numba), an OBB-tree broad phase over every checked pair (numba,
:mod:`arduinobot.planner.collision.bounds.obbtree`), and FCL's exact narrow phase only for the pairs the trees cannot
separate; FCL objects are built once and only moved.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import fcl
import numpy as np
from numpy.typing import ArrayLike

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.planner.cache import ArtifactCache
from arduinobot.planner.collision.acm import AllowedCollisionMatrix
from arduinobot.planner.collision.assembly import SceneBodies, carried_touch
from arduinobot.planner.collision.bodies import RobotBodies
from arduinobot.planner.collision.bounds.hulls import HullBounds
from arduinobot.planner.collision.bounds.obbtree import Forest, pair_candidates, state_candidates
from arduinobot.planner.collision.bounds.parts import PartBounds
from arduinobot.planner.collision.compiled import Direct
from arduinobot.planner.collision.proof.advance import (
    SweepCarry,
    Work,
    joint_reach,
    pair_weights,
    sweep,
    tree_lower_bound,
)
from arduinobot.planner.collision.proof.body_speed import moving_by_static
from arduinobot.planner.collision.table import BodyKind, BodyTable
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import (
    AttachedObject,
    Obstacle,
    resolve_attached,
    validate_obstacles,
)

_log = logging.getLogger(__name__)
_STACK = 4096
# [m] distance bounds for the clearance stop here: pairs farther apart sort last
_CLEARANCE_CAP = 0.3


def _validate_clouds(clouds: Sequence[CloudObstacle], obstacles: Sequence[Obstacle],
                     attached: Sequence[AttachedObject], links: Sequence[str]
                     ) -> tuple[CloudObstacle, ...]:
    taken = {o.id for o in obstacles} | {a.id for a in attached} | set(links)
    for i, c in enumerate(clouds):
        if not isinstance(c, CloudObstacle):
            raise InvalidRequest(f"expected a CloudObstacle, got {type(c).__name__}",
                                 field=f"clouds[{i}]")
        if c.id in taken:
            raise InvalidRequest(f"id '{c.id}' is taken (a link, object or cloud)",
                                 field=f"clouds[{i}].id")
        taken.add(c.id)
    return tuple(clouds)


@dataclass(frozen=True)
class StateCheck:
    """The outcome of checking one state.

    Attributes:
        valid: no checked pair collides (or comes closer than the padding).
        pairs: every colliding pair, (link, link) or (link, obstacle id).
        clearance: minimum distance [m] over the checked pairs, if asked for (0 when
            colliding).
        closest: the pair at that distance, if asked for.
    """

    valid: bool
    pairs: tuple[tuple[str, str], ...]
    clearance: float | None = None
    closest: tuple[str, str] | None = None


class CollisionWorld:
    """Self and scene collision checking for one robot in one scene.

    Args:
        description: the loaded robot.
        obstacles: scene obstacles (ids must be unique and differ from link names).
        attached: objects the robot carries, each posed in its link's frame: checked
            against the obstacles and every link but its touch links (none given: the
            defaults of :func:`arduinobot.scene.obstacles.default_touch_links`), certified as the
            links are (a carried body's motion bound is its link's over its extent).
        padding: a state is invalid when a checked pair is closer than this [m].
        acm: pairs to skip; default: joint-connected and rigidly attached links plus
            the SRDF's disabled pairs (:meth:`AllowedCollisionMatrix.for_description`).
        bodies: the robot's collision geometry from another world of the same
            description (see :meth:`with_scene`); built here if not given.
        cache: where built OBB trees are kept between runs (by content), if anywhere.
        narrow_phase: False: a moving pair the OBB trees cannot prove farther apart than
            the padding counts as colliding, without asking FCL (conservative: it may
            refuse free states, never accepts a colliding one; several times cheaper near
            contact). Pairs that never move are always decided exactly.
    """

    def __init__(self, description: Description, *, obstacles: Sequence[Obstacle] = (),
                 padding: float = 0.0, acm: AllowedCollisionMatrix | None = None,
                 bodies: RobotBodies | None = None, cache: ArtifactCache | None = None,
                 narrow_phase: bool = True,
                 attached: Sequence[AttachedObject] = (),
                 clouds: Sequence[CloudObstacle] = ()) -> None:
        if not np.isfinite(padding) or padding < 0:
            raise InvalidRequest(f"{padding!r} must be a finite number >= 0 [m]",
                                 field="padding")
        self.description = description
        self.kin = Kinematics(description.robot)
        self.padding = float(padding)
        self.narrow_phase = narrow_phase
        self.acm = acm if acm is not None else AllowedCollisionMatrix.for_description(description)
        self.obstacles = validate_obstacles(obstacles, link_names=self.kin.link_names)
        self.attached = resolve_attached(description, tuple(attached),
                                         obstacles=self.obstacles)
        self.clouds = _validate_clouds(clouds, self.obstacles, self.attached,
                                       self.kin.link_names)
        self.checks = 0
        robot = description.robot
        if bodies is None:
            bodies = RobotBodies.build(description, self.kin, cache=cache)
        elif bodies.description is not description:
            raise InvalidRequest("bodies were built for another description", field="bodies")
        self.bodies = bodies
        scene = SceneBodies.assemble(bodies, self.obstacles, self.attached,
                                     link_index=dict(self.kin.link_index),
                                     clouds=self.clouds)
        names = scene.names
        self._objs = scene.objects
        self._surfaces = scene.surfaces
        self._tiled = scene.clouds
        #: every body's OBB tree, for the kernels
        self.forest = Forest.of(list(scene.trees))
        self._hull_bounds = HullBounds(list(scene.hulls), scene.poses)
        #: every body's convex hull packed, for the kernels
        self.hulls = self._hull_bounds.pack
        self._part_bounds = PartBounds(list(scene.parts))
        #: the kinematic chain, for the kernels
        self.chain = self.kin.chain
        index, fixed = scene.checked_pairs(self.acm, carried_touch(self.attached))
        # [m/rad] how fast each pair can close in per joint, for conservative advancement
        reach = bodies.proofs.get("joint_reach")
        if reach is None:  # the robot's links' reach: once per robot, not per world
            reach = bodies.proofs["joint_reach"] = tuple(
                joint_reach(robot, link, pts) for link, pts in bodies.points)
        weight = pair_weights(robot, self.kin.joint_names, list(scene.points), index,
                              known=reach)
        # per pair, the body that moves by a static one (its local speed bounds the pair's
        # steps too), or -1
        links = np.array(scene.links, dtype=np.int64)
        mover = np.array([moving_by_static(int(a), int(b), links, self.chain)
                          for a, b in index], np.int64)
        self._placed = np.full(len(names), -1, dtype=np.int64)
        self._stamp = 0
        self._creq = fcl.CollisionRequest()
        self._dreq = fcl.DistanceRequest()
        #: every body, its kind and pose, and the checked pairs (frozen)
        self.table = BodyTable.build(names, scene.kinds, scene.links, scene.poses, index,
                                     weight, mover, n_links=len(self.kin.link_names),
                                     fixed=fixed)
        # the table's links and carried bodies as Python values (read per narrow-phase call)
        self._link_of = scene.links
        self._carried = frozenset(self.table.of_kind(BodyKind.CARRIED))
        # Pairs of bodies that never move are decided once, here.
        poses0 = self._poses_of(np.zeros(self.kin.dof), np.empty((self.table.slots, 4, 4)))
        hits = tuple((names[a], names[b]) for a, b in fixed
                     if self._narrow(poses0, a, b, exact=True))
        self.table = replace(self.table, fixed_hits=hits)
        self._poses = np.empty((self.table.slots, 4, 4))
        #: bounds derived from this world alone, kept with it so every certifier of it
        #: shares them (the ladder's still pairs: :func:`.ladder.still_bound`)
        self.remembered: dict[tuple[int, float, bytes], float] = {}
        self._cand = np.zeros(len(index), dtype=np.int64)
        self._work = Work.of(self.table.slots, _STACK)
        # the two kernels called per state and per sweep resume, past numba's dispatcher
        # (its typing of the tables' arrays cost ~4 us a call: :mod:`.compiled`)
        self._state_candidates = Direct(state_candidates)
        self._sweep_kernel = Direct(sweep)
        # [m] how far ahead one distance bound is asked to prove a pair free: a short
        # proof is a shallow tree descent, and a sampled edge's states are close together
        # (the same decisions as any cap; measured: docs/bench.md)
        self.horizon = 0.01
        _log.info("collision world: %d bodies, %d moving pairs, %d fixed pairs (%d colliding)",
                  len(names), len(index), len(fixed), len(hits))

    # -- the table by name (the public names other modules read) ------------------------
    @property
    def body_names(self) -> tuple[str, ...]:
        """Every body's name, in the table's order."""
        return self.table.names

    @property
    def link_bodies(self) -> tuple[str, ...]:
        """The links that have collision geometry."""
        return tuple(self.table.names[b] for b in self.table.of_kind(BodyKind.LINK))

    @property
    def pair_names(self) -> tuple[tuple[str, str], ...]:
        """The checked pairs some motion moves, by name (indices of the kernels' pairs)."""
        return self.table.pair_names

    # -- internals -------------------------------------------------------------------
    def with_scene(self, obstacles: Sequence[Obstacle] = (), *,
                   padding: float | None = None,
                   acm: AllowedCollisionMatrix | None = None,
                   narrow_phase: bool | None = None,
                   attached: Sequence[AttachedObject] | None = None,
                   clouds: Sequence[CloudObstacle] | None = None) -> CollisionWorld:
        """A world for other obstacles (and padding [m], allowed pairs, narrow phase,
        carried objects or clouds), sharing this one's robot geometry (and by default its
        other settings, its carried objects and clouds too): milliseconds instead of a
        rebuild (a new cloud's geometry is built once per content)."""
        return CollisionWorld(self.description, obstacles=obstacles,
                              padding=self.padding if padding is None else padding,
                              acm=self.acm if acm is None else acm, bodies=self.bodies,
                              narrow_phase=self.narrow_phase if narrow_phase is None
                              else narrow_phase,
                              attached=self.attached if attached is None else attached,
                              clouds=self.clouds if clouds is None else clouds)

    def _place(self, poses: np.ndarray, b: int) -> None:
        # move body b's FCL object once per state (stamped), never for obstacles (a
        # cloud, which has none, is one)
        obj = self._objs[b]
        if self._link_of[b] < 0 or self._placed[b] == self._stamp or obj is None:
            return
        t = self.body_pose(poses, b)
        obj.setRotation(t[:3, :3])
        obj.setTranslation(t[:3, 3])
        self._placed[b] = self._stamp

    def body_pose(self, poses: np.ndarray, b: int) -> np.ndarray:
        """Body ``b``'s world pose (4, 4) at link poses ``poses`` (n_links, 4, 4): its
        link's, that times its offset for a carried object, its own for an obstacle."""
        f = self._link_of[b]
        if f < 0:
            return self.table.bodies.pose[b]
        return poses[f] @ self.table.bodies.pose[b] if b in self._carried else poses[f]

    def _narrow(self, poses: np.ndarray, a: int, b: int, *, exact: bool = False) -> bool:
        if not (exact or self.narrow_phase):
            return True  # the trees could not prove the pair apart: conservatively a hit
        self._place(poses, a)
        self._place(poses, b)
        if b in self._tiled and self.padding > 0:
            return self._tiled[b].within(self._objs[a], *self._world_box(poses, a),
                                         self.padding)
        if self.padding > 0:
            return self._distance(poses, a, b) < self.padding
        if b in self._tiled:
            return self._tiled[b].collide(self._objs[a], *self._world_box(poses, a))
        return fcl.collide(self._objs[a], self._objs[b], self._creq, fcl.CollisionResult()) > 0

    def _distance(self, poses: np.ndarray, a: int, b: int, *, surface: bool = False) -> float:
        # surface: a box obstacle b by its 12 triangles (only where b holds no body); a
        # cloud (always the later body: clouds come last) by its tiles near a's box
        if b in self._tiled:
            return self._tiled[b].distance(self._objs[a], *self._world_box(poses, a))
        other = self._surfaces.get(b, self._objs[b]) if surface else self._objs[b]
        d = fcl.distance(self._objs[a], other, self._dreq, fcl.DistanceResult())
        return max(float(d), 0.0)

    def _world_box(self, poses: np.ndarray, b: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # body b's box in the world: its tree's root box (centre [m], axes as columns,
        # half extents [m]), posed
        t, f = self.body_pose(poses, b), self.forest
        r = f.root[b]
        return t[:3, :3] @ f.center[r] + t[:3, 3], t[:3, :3] @ f.axes[r], f.half[r]

    def _candidates(self, poses: np.ndarray, out: np.ndarray) -> int:
        return pair_candidates(poses, self.table.bodies, self.table.pairs.index, self.forest,
                               self.padding, self._work.stack, out)

    def _state_hits(self, poses: np.ndarray, cand: np.ndarray, *, first: bool) -> list[int]:
        self._stamp += 1
        hits = []
        index = self.table.pairs.index
        for p in np.flatnonzero(cand):
            a, b = index[p]
            if self._narrow(poses, a, b):
                hits.append(int(p))
                if first:
                    break
        return hits

    def _poses_of(self, q: ArrayLike, out: np.ndarray | None = None) -> np.ndarray:
        # the kernels' pose slots: the links', then the carried objects'
        poses = self.kin.link_poses(q, out=self._poses if out is None else out)
        for b in self._carried:
            poses[self.table.bodies.frame[b]] = self.body_pose(poses, b)
        return poses

    # -- public -----------------------------------------------------------------------
    @property
    def dof(self) -> int:
        return self.kin.dof

    def is_valid(self, q: ArrayLike) -> bool:
        """True if state ``q`` (shape (dof,), [rad]) collides with nothing."""
        self.checks += 1
        if self.table.fixed_hits:
            return False
        q = np.ascontiguousarray(q, dtype=float)
        if q.shape != (self.dof,):
            self.kin.link_poses(q)  # raises its InvalidRequest naming the joints
        t, poses = self.table, self._poses
        if self._state_candidates.call(q, self.chain, t.bodies, t.pairs.index, self.forest,
                                       self.padding, poses, self._work.stack,
                                       self._cand) == 0:
            return True
        return not self._state_hits(poses, self._cand, first=True)

    def pair_distance(self, q: ArrayLike, pair: int, *,
                      kind: Literal["exact", "hulls", "parts"] = "exact",
                      direction: np.ndarray | None = None) -> float:
        """The distance [m] between the bodies of checked pair ``pair`` (an index into
        :attr:`pair_names`) at a state ``q`` (shape (dof,)), or a lower bound on it, by
        ``kind`` (the rungs of the certifier's ladder, :mod:`.ladder`, say when each):

        - ``"exact"``: FCL's exact distance (0.3-4 ms on CAD links), at a state where
          neither body is inside the other (a free state, or one reached from a free
          state without contact); 0 when they touch. A box obstacle is measured by its
          surface there (the same distance, faster).
        - ``"hulls"``: the convex hulls' bound at any state (:mod:`.hulls`, ~20 us; 0 or
          less where the hulls touch). ``direction``: as for :meth:`.HullBounds.bound`.
        - ``"parts"``: the part hulls' bound (:mod:`.parts`, tens of us; tight near a
          concave body, where the hulls touch); -inf where neither body has parts (the
          hulls' bound is as good).
        """
        a, b = (int(x) for x in self.table.pairs.index[pair])
        if kind == "parts" and not self._part_bounds.split(a, b):
            return -np.inf
        poses = self._poses_of(q)
        if kind == "hulls":
            return self._hull_bounds.bound(a, self.body_pose(poses, a), b,
                                           self.body_pose(poses, b), direction=direction)
        if kind == "parts":
            return self._part_bounds.bound(a, self.body_pose(poses, a), b,
                                           self.body_pose(poses, b))
        if kind != "exact":
            raise ValueError(f"kind must be exact, hulls or parts, not {kind!r}")
        self._stamp += 1
        self._place(poses, a)
        self._place(poses, b)
        return self._distance(poses, a, b, surface=True)

    def lower_bound(self, q: ArrayLike) -> float:
        """A lower bound [m] on the distance between the moving checked pairs at ``q``
        (shape (dof,)), from the OBB trees alone (no FCL); at most 0.3 m."""
        lb = self._tree_bounds(self._poses_of(q), list(map(tuple, self.table.pairs.index)))
        return float(lb.min()) if len(lb) else _CLEARANCE_CAP

    def rigid_pairs(self, joints: Sequence[str]) -> tuple[tuple[str, str], ...]:
        """The checked pairs whose distance no motion of ``joints`` changes (both bodies
        move with them rigidly, or neither moves: a gripper's fingers in an arm motion)."""
        cols = [self.kin.joint_names.index(j) for j in joints]
        return tuple(self.pair_names[p] for p in range(len(self.pair_names))
                     if self.table.pairs.weight[p, cols].max() < 1e-9)

    def _tree_bounds(self, poses: np.ndarray, pairs: list[tuple[int, int]]) -> np.ndarray:
        # OBB-tree lower bounds [m] of body pairs at link poses ``poses``, capped
        f = self.forest
        w = self._work
        scratch = np.empty((8, 3, 3))
        lb = np.empty(len(pairs))
        for k, (a, b) in enumerate(pairs):
            lb[k] = min(tree_lower_bound(self.body_pose(poses, a), f.root[a],
                                         self.body_pose(poses, b), f.root[b], f.center,
                                         f.axes, f.half, f.left, f.right, 0.0, _CLEARANCE_CAP,
                                         w.stack, w.gaps, scratch), _CLEARANCE_CAP)
        return lb

    def check(self, q: ArrayLike, *, clearance: bool = False) -> StateCheck:
        """Every colliding pair at ``q``, and the minimum clearance if asked."""
        self.checks += 1
        poses = self._poses_of(q)
        cand = np.zeros(len(self.table.pair_names), dtype=np.int64)
        self._candidates(poses, cand)
        hits = self._state_hits(poses, cand, first=False)
        pairs = self.table.fixed_hits + tuple(self.pair_names[p] for p in hits)
        if not clearance:
            return StateCheck(valid=not pairs, pairs=pairs)
        dist, closest = self._clearance(poses) if not pairs else (0.0, pairs[0])
        return StateCheck(valid=not pairs, pairs=pairs, clearance=dist, closest=closest)

    def _clearance(self, poses: np.ndarray, best: float = np.inf) -> tuple[float, tuple[str, str]]:
        # OBB-tree lower bounds per pair (capped: far pairs sort last at the cap); FCL's
        # exact distance only for pairs whose bound could beat the best distance so far.
        self._stamp += 1
        allp = list(map(tuple, self.table.pairs.index)) + list(self.table.fixed)
        if not allp:
            return float("inf"), ("", "")
        lb = self._tree_bounds(poses, allp)
        closest = (self.body_names[allp[0][0]], self.body_names[allp[0][1]])
        for k in np.argsort(lb, kind="stable"):
            if lb[k] >= best:
                break
            a, b = int(allp[k][0]), int(allp[k][1])
            self._place(poses, a)
            self._place(poses, b)
            d = self._distance(poses, a, b)
            if d < best:
                best, closest = d, (self.body_names[a], self.body_names[b])
        return float(best), closest

    def _sweep(self, qs: np.ndarray, start: int, stop_early: bool, cum: np.ndarray,
               carry: SweepCarry, out: np.ndarray) -> int:
        t = self.table
        return self._sweep_kernel.call(qs, start, stop_early, cum, carry, self.chain,
                                       t.bodies, t.pairs, self.forest, self.padding,
                                       self.horizon, self._work, out)

    def _budget(self) -> SweepCarry:
        # the sweep's per-pair proof, carried between its resumed calls
        return SweepCarry.of(len(self.table.pair_names), self.dof)

    def sweep_candidates(self, qs: ArrayLike) -> np.ndarray:
        """(state, pair) flags, shape (m, n_pairs) int8, for states ``qs`` (m, dof) walked
        in order: 0 where conservative advancement proves the pair apart (farther than
        the padding), 1 where the narrow phase must decide."""
        qs = np.ascontiguousarray(qs, dtype=float).reshape(-1, self.dof)
        out = np.zeros((len(qs), len(self.table.pair_names)), dtype=np.int8)
        self._sweep(qs, 0, False, np.empty_like(qs), self._budget(), out)
        return out

    def first_invalid(self, qs: ArrayLike) -> int:
        """Index of the first colliding state of ``qs`` (shape (m, dof)), -1 if none.

        Every state is decided (nothing between states is implied): pairs that
        conservative advancement (:mod:`arduinobot.planner.collision.proof.advance`) proves apart are skipped, the
        rest go to the narrow phase. The walk stops at the first colliding state.
        """
        qs = np.ascontiguousarray(qs, dtype=float).reshape(-1, self.dof)
        self.checks += len(qs)
        m = len(qs)
        if m == 0:
            return -1
        if self.table.fixed_hits:
            return 0
        out = np.zeros((m, len(self.table.pair_names)), dtype=np.int8)
        cum, budget = np.empty_like(qs), self._budget()
        i = self._sweep(qs, 0, True, cum, budget, out)
        while i < m:
            # the sweep stopped at state i with its link poses in its work buffer
            if self._state_hits(self._work.poses, out[i], first=True):
                return int(i)
            i = self._sweep(qs, i + 1, True, cum, budget, out)
        return -1

    def min_clearance(self, qs: ArrayLike) -> tuple[float, tuple[str, str]]:
        """Minimum clearance [m] over states ``qs`` (shape (m, dof)) and its pair."""
        qs = np.ascontiguousarray(qs, dtype=float).reshape(-1, self.dof)
        self.checks += len(qs)
        best, closest = float("inf"), ("", "")
        if self.table.fixed_hits:
            return 0.0, self.table.fixed_hits[0]
        batch = None if self._carried else self.kin.link_poses_batch(qs)
        for i in range(len(qs)):
            # a carried object's pose slot is filled per state
            d, c = self._clearance(self._poses_of(qs[i]) if batch is None else batch[i], best)
            if d < best:
                best, closest = d, c
        return best, closest
