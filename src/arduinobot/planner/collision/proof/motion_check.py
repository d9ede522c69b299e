"""Checking straight joint-space motions, and OMPL's checkers built on it.

Two checks of an edge a -> b, both at a fixed joint step [rad] (not OMPL's fraction of
the space's extent): :func:`sampled_motion_valid` checks its states that far apart in one
batched call (fast: what search and shortcutting try thousands of times), and
:func:`motion_valid` proves it free over its whole length with
:class:`arduinobot.planner.collision.proof.certify.Certifier` (what a returned path must pass).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np
import ompl.base as ob
from numpy.typing import ArrayLike

from arduinobot.planner.collision.proof.certify import Certifier


class StateChecker(Protocol):
    """What search and shortcutting ask of a world (a :class:`CollisionWorld` is one; so
    is :class:`arduinobot.planner.planning.pathfinding.room.Guarded`)."""

    def is_valid(self, q: ArrayLike) -> bool: ...

    def first_invalid(self, qs: ArrayLike) -> int: ...


def interpolate(path: np.ndarray, step: float) -> np.ndarray:
    """Samples along a polyline of joint vectors (shape (k, dof)) with no joint moving
    more than ``step`` [rad] between consecutive samples; includes every vertex."""
    path = np.asarray(path, float)
    if len(path) < 2:
        return path.copy()
    parts = []
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.max(np.abs(b - a)) / step)))
        t = np.arange(n)[:, None] / n
        parts.append(a + t * (b - a))
    parts.append(path[-1:])
    return np.concatenate(parts)


def sampled_motion_valid(world: StateChecker, a: np.ndarray, b: np.ndarray,
                         step: float) -> bool:
    """True if every state of the straight motion a -> b, ``step`` [rad] apart (ends
    excluded but b), is free. Between states nothing is proven."""
    n = max(1, int(np.ceil(np.max(np.abs(b - a)) / step)))
    if n <= 1:
        return world.is_valid(b)
    # the end and the middle first: most edges a search tries are refused, and walking
    # them in order from a costs half of one on average (pillars, arm and gripper: 729
    # of 1033 edges refused, 64% of the time spent on edges); same verdict either way
    mid = n // 2 if n >= 4 else 0
    if not world.is_valid(b) or (mid and not world.is_valid(a + mid / n * (b - a))):
        return False
    k = np.arange(1, n)  # the rest: b and the middle are free already
    t = (k[k != mid] if mid else k)[:, None] / n
    return world.first_invalid(a + t * (b - a)) < 0


def motion_valid(certifier: Certifier, a: np.ndarray, b: np.ndarray, step: float) -> bool:
    """True if the straight motion a -> b is certified free over its whole length
    (its states ``step`` [rad] apart are checked first)."""
    return certifier.path(np.array([a, b]), sample_step=step).free


class StateCodec:
    """Maps OMPL states over a group's joints to full actuated vectors."""

    def __init__(self, group_index: np.ndarray, base: np.ndarray) -> None:
        self.index = group_index
        self.base = base.copy()
        self.n = len(group_index)

    def full(self, s: ob.State) -> np.ndarray:
        q = self.base.copy()
        for i in range(self.n):
            q[self.index[i]] = s[i]
        return q

    def put(self, q: np.ndarray, s: ob.State) -> None:
        for i in range(self.n):
            s[i] = float(q[self.index[i]])


class ValidityChecker(ob.StateValidityChecker):
    """OMPL state validity through :meth:`CollisionWorld.is_valid`."""

    def __init__(self, si: ob.SpaceInformation, world: StateChecker, codec: StateCodec):
        super().__init__(si)
        self.world, self.codec = world, codec

    def isValid(self, s: ob.State) -> bool:  # noqa: N802 (OMPL's name)
        return bool(self.world.is_valid(self.codec.full(s)))


class MotionChecker(ob.MotionValidator):
    """OMPL motion validation through ``edge_free(a, b) -> bool`` on full joint vectors
    (:func:`sampled_motion_valid` or :func:`motion_valid`)."""

    def __init__(self, si: ob.SpaceInformation, edge_free: Callable[[np.ndarray, np.ndarray],
                 bool], codec: StateCodec):
        super().__init__(si)
        self.edge_free, self.codec = edge_free, codec

    def checkMotion(self, s1: ob.State, s2: ob.State, *rest: object) -> bool:  # noqa: N802
        return bool(self.edge_free(self.codec.full(s1), self.codec.full(s2)))
