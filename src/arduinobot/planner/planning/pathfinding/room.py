"""Room kept per pair: the worlds detours are searched in.

A detour is first searched with every pair the group moves kept ``room`` farther apart
than the clearance (by the OBB trees alone: :meth:`PathPlanner.roomy
<arduinobot.planner.planning.pathfinding.paths.PathPlanner.roomy>`). A pair that lacks that room where the
motion starts or ends, and cannot leave it by a short edge (a camera bolted a millimetre
from the turntable, which every joint_1 motion turns past it), used to switch the room
off for every pair. :class:`Guarded` lets such a pair lose it alone: the roomy world
no longer checks it, a second world checks just those pairs at the plain clearance
(with the narrow phase), and a state is free when both say so. An end without the
room leaves it first by a short free edge (:func:`escape`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from arduinobot.planner.collision.proof.motion_check import StateChecker
from arduinobot.planner.collision.world import CollisionWorld

__all__ = ["Guarded", "StateChecker", "escape", "roomy_world", "short_of_room"]

@dataclass(frozen=True, eq=False)
class Guarded:
    """A roomy world whose ``lost`` pairs are checked by ``guard`` instead.

    Attributes:
        roomy: every pair the group moves but ``lost`` kept the room apart (trees only).
        guard: only the ``lost`` pairs, at the exact world's clearance.
        lost: the pairs that lost the room, by name.
    """

    roomy: CollisionWorld
    guard: CollisionWorld
    lost: tuple[tuple[str, str], ...]

    @classmethod
    def of(cls, world: CollisionWorld, joints: tuple[str, ...],
           lost: tuple[tuple[str, str], ...], room: float) -> Guarded:
        """The roomy world of ``joints`` (:func:`roomy_world`) where the pairs ``lost``
        lose the room alone: checked by the guard at ``world``'s clearance."""
        roomy = roomy_world(world, joints, room, lost=lost)
        keep = set(lost)
        guard = world.with_scene(world.obstacles, acm=world.acm.with_pairs(
            [n for n in world.pair_names if n not in keep], reason="Kept apart with room"))
        return cls(roomy, guard, lost)

    def is_valid(self, q: ArrayLike) -> bool:
        """Free in both worlds."""
        return self.roomy.is_valid(q) and self.guard.is_valid(q)

    def first_invalid(self, qs: ArrayLike) -> int:
        """Index of the first state of ``qs`` (m, dof) either world refuses, -1 if
        none (the guard walks only the states before the roomy world's first)."""
        qs = np.asarray(qs, dtype=float)
        a = self.roomy.first_invalid(qs)
        if a == 0:
            return 0
        b = self.guard.first_invalid(qs if a < 0 else qs[:a])
        return b if b >= 0 else a


def roomy_world(world: CollisionWorld, joints: tuple[str, ...], room: float, *,
                lost: tuple[tuple[str, str], ...] = ()) -> CollisionWorld:
    """``world`` with every pair ``joints`` move kept ``room`` [m] farther apart, by
    the trees alone (no narrow phase); pairs they do not move, and the pairs ``lost``,
    are not checked (a gripper's fingers stay as close as they are)."""
    acm = world.acm.with_pairs(world.rigid_pairs(joints), reason="Rigid in the group")
    if lost:
        acm = acm.with_pairs(lost, reason="Short of room at an end")
    return world.with_scene(world.obstacles, padding=world.padding + room,
                            narrow_phase=False, acm=acm)


def short_of_room(world: CollisionWorld, roomy: CollisionWorld, ends: ArrayLike, room: float,
                  *, exact: bool = True) -> tuple[tuple[str, str], ...]:
    """The pairs of ``roomy`` that lack ``room`` [m] beyond ``world``'s clearance at some
    state of ``ends`` (k, dof, free states of ``world``), by name, in ``roomy``'s pair
    order: those its trees cannot prove it for, and with ``exact`` only those of them
    whose exact distance there is short too (the trees are a few tenths of the distance
    on CAD meshes: a pair they alone doubt can still leave by a short edge)."""
    ends = np.atleast_2d(np.asarray(ends, dtype=float))
    flags = roomy.sweep_candidates(ends)
    index = {n: p for p, n in enumerate(world.pair_names)}
    out = []
    for p in np.flatnonzero(flags.any(axis=0)):
        name = roomy.pair_names[p]
        if not exact or any(world.pair_distance(q, index[name]) < world.padding + room
                            for q, f in zip(ends, flags[:, p]) if f):
            out.append(name)
    return tuple(out)


def escape(end: np.ndarray, toward: np.ndarray, cols: np.ndarray, roomy: StateChecker,
           limits: np.ndarray, rng: np.random.Generator,
           edge_free: Callable[[np.ndarray, np.ndarray], bool]) -> np.ndarray | None:
    """``end`` (dof,) if ``roomy`` finds it free (it has the room), else a state with
    room that a straight edge ``edge_free`` accepts reaches from it, moving the joints
    ``cols`` (indices) within ``limits`` (len(cols), 2) [rad]: at the shortest distance
    of 0.05, 0.1, 0.2, 0.4 rad where one does, the first of the directions tried
    (towards ``toward``, then 8 drawn from ``rng``); None if none does.

    Ranking the states found by their tree bound (so the edge's proof needs fewer exact
    distances) measured no faster on the course model: the bounds cost what the proof
    saved."""
    if roomy.is_valid(end):
        return end
    dirs = [toward[cols] - end[cols]] + list(rng.normal(size=(8, len(cols))))
    for r in (0.05, 0.1, 0.2, 0.4):
        for d in dirs:
            n = float(np.linalg.norm(d))
            if n == 0:
                continue
            e = end.copy()
            e[cols] = np.clip(end[cols] + r * d / n, limits[:, 0], limits[:, 1])
            if roomy.is_valid(e) and edge_free(end, e):
                return e
    return None
