"""Grasp candidates for an object, from its shape and the claw's geometry, only those the
arm can reach.

A 3-joint arm cannot choose its orientation: where its fingertips are decides how the
claw points. So a candidate is a point to put the fingertips' midpoint at (the object's
centre, or higher up it) and a way in (``fingers``: along the claw's own axis as it is at
that point; ``above``: straight down), each solved for the arm's joints (bounded least
squares from fixed seeds: deterministic); the claw's closing axis there gives the width
the object has between the fingers (its mesh's extent along it, so a box, a cylinder, a
sphere and a mesh are one case). Candidates come best first: the claw most nearly
pointing down (an object resting on a support is best taken from above).

An arm of more than 3 joints (the SO-101's 5) can choose: there the claw is also made to
point the way in (``above``: down; ``fingers``: level, away from the arm's base, its jaws
closing level), within :data:`AIM_TOLERANCE`; a miss beyond it counts in the residual as
the arc it makes at :data:`LEVER`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from arduinobot.planner.tasks.claw import Claw
from arduinobot.scene.obstacles import Obstacle

#: [m] a grasp point (and its approach point) reached within this counts as reached
REACH_TOLERANCE = 1e-3
#: [m] the least gap left on each side of the object as the fingers go in
CLEARANCE = 0.005
#: [m] the fingers open this much wider than the object on each side (if they can)
OPEN_MARGIN = 0.02
APPROACHES = ("fingers", "above")
#: [m] the highest candidate grasps this far below the object's top
TOP_MARGIN = 0.005
#: [m] an arm that can point its claw: a direction's miss [rad] counts as the arc at this
LEVER = 0.1
#: [rad] ... beyond this much (the claw's axis, from its meshes, is itself a few degrees
#: off the tool's, and a wrist at its limit may not point quite straight down)
AIM_TOLERANCE = np.radians(15.0)


@dataclass(frozen=True)
class Grasp:
    """One candidate: ``name``, the fingertips' midpoint at the grasp ``target`` [m]
    (world), the arm's state there (``q_grasp``) and at the approach's start
    (``q_pre``), full vectors [rad] in the planner's joint order; the object's
    ``width`` [m] between the fingers, the leader's ``open`` and ``close`` values
    [rad]; ``residual`` [m] the larger miss of the two states."""

    name: str
    approach: str
    target: np.ndarray
    q_grasp: np.ndarray
    q_pre: np.ndarray
    width: float
    open: float
    close: float
    residual: float
    down: float  # the claw's axis against straight down (1: pointing down)


@dataclass(frozen=True)
class Candidates:
    """What the enumeration found: the reachable candidates (best first), and of the
    unreachable ones the closest (its residual [m] and name), and how many there were."""

    reachable: tuple[Grasp, ...]
    tried: int
    closest_residual: float | None = None
    closest_name: str | None = None


def vertices(obstacle: Obstacle) -> np.ndarray:
    """The obstacle's mesh vertices in the world [m], shape (n, 3)."""
    pts = np.asarray(obstacle.geometry.triangles().vertices, float)
    t = obstacle.pose()
    return pts @ t[:3, :3].T + t[:3, 3]


def extent(points: np.ndarray, axis: np.ndarray) -> float:
    """[m] the points' extent along the unit ``axis``."""
    s = points @ axis
    return float(s.max() - s.min())


class Reach:
    """Where the arm puts a point fixed in the claw's link: the arm joints solved by
    bounded least squares from the given state, else from a fixed grid of seeds (the
    first that reaches wins; none: the closest miss)."""

    def __init__(self, kin: object, link: str, arm: Sequence[int], lower: np.ndarray,
                 upper: np.ndarray) -> None:
        self.kin, self.link, self.arm = kin, link, list(arm)
        self.lower, self.upper = lower[self.arm], upper[self.arm]
        # two values of each of the three joints that place the claw, the middle of the
        # rest (a wrist): 8 seeds on any arm (a 5-joint arm's 32 took 23 s a pick)
        grid = [np.linspace(lo, hi, 4)[1:3] if i < 3 else [(lo + hi) / 2]
                for i, (lo, hi) in enumerate(zip(self.lower, self.upper))]
        self.seeds = [np.array(s) for s in itertools.product(*grid)]

    def pose(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(self.kin.link_pose(q, self.link))  # type: ignore[attr-defined]

    @property
    def can_point(self) -> bool:
        """Whether the arm has joints beyond the three that place a point."""
        return len(self.arm) > 3

    def solve(self, point: np.ndarray, target: np.ndarray, q0: np.ndarray, *,
              point_along: tuple[np.ndarray, np.ndarray] | None = None,
              level: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """The full state (``q0`` with the arm joints solved) closest to putting
        ``point`` (link frame) at ``target`` (world), and its miss [m].

        ``point_along`` (a unit vector in the link's frame, the world unit direction it
        should take) and ``level`` (a link-frame unit vector to keep horizontal), on an
        arm that :attr:`can_point`: their misses [rad] beyond :data:`AIM_TOLERANCE`
        count at :data:`LEVER` [m]."""
        aims = point_along if self.can_point else None
        flat = level if self.can_point else None

        def misses(q: np.ndarray) -> np.ndarray:
            t = self.pose(q)
            out = [t[:3, :3] @ point + t[:3, 3] - target]
            if aims is not None:
                cos = float(np.clip((t[:3, :3] @ aims[0]) @ aims[1], -1.0, 1.0))
                out.append(np.array([LEVER * max(0.0, np.arccos(cos) - AIM_TOLERANCE)]))
            if flat is not None:
                sin = float(np.clip((t[:3, :3] @ flat)[2], -1.0, 1.0))
                out.append(np.array([LEVER * max(0.0, abs(np.arcsin(sin)) - AIM_TOLERANCE)]))
            return np.concatenate(out)

        best: tuple[float, np.ndarray] | None = None
        for seed in [np.clip(q0[self.arm], self.lower, self.upper), *self.seeds]:
            def miss(x: np.ndarray) -> np.ndarray:
                q = q0.copy()
                q[self.arm] = x
                return misses(q)
            r = least_squares(miss, seed, bounds=(self.lower, self.upper), xtol=1e-10,
                              ftol=1e-12, gtol=1e-12, max_nfev=200)
            m = miss(r.x)
            err = float(max(np.linalg.norm(m[:3]), np.linalg.norm(m[3:]) if len(m) > 3
                            else 0.0))
            if best is None or err < best[0]:
                best = (err, r.x)
            if err <= REACH_TOLERANCE:
                break  # from the given state first: the solution nearest to it
        assert best is not None
        q = q0.copy()
        q[self.arm] = best[1]
        return q, best[0]


def enumerate_grasps(claw: Claw, reach: Reach, obstacle: Obstacle, q0: np.ndarray, *,
                     approach: float, leader: int, hints: dict[str, object] | None = None
                     ) -> Candidates:
    """Every candidate for ``obstacle`` (``hints``: ``approach`` one of
    :data:`APPROACHES`, ``height`` [m] above the object's centre), solved from ``q0``;
    ``approach`` [m] the way in; ``leader`` the gripper leader's index in the state."""
    hints = hints or {}
    pts = vertices(obstacle)
    centre = (pts.min(0) + pts.max(0)) / 2
    height = float(pts[:, 2].max() - pts[:, 2].min())
    # the centre, higher up, and just under the top (a short object: the fingertips
    # would reach the support below a lower grasp)
    heights = ([float(hints["height"])] if "height" in hints  # type: ignore[arg-type]
               else [0.0, height / 4, max(height / 2 - TOP_MARGIN, height / 4)])
    ways = [str(hints["approach"])] if "approach" in hints else list(APPROACHES)
    found: list[Grasp] = []
    closest: tuple[float, str] | None = None
    tried = 0
    for dz, way in itertools.product(heights, ways):
        tried += 1
        name = f"{way}, {'centre' if dz == 0 else f'{dz:+.3f} m'}"
        target = centre + np.array([0.0, 0.0, dz])
        aim = _aim(way, target, claw)
        # the width decides the close value, the close value where the tips are: the
        # width across the claw as it is at the centre's grasp, once refined
        q = q0.copy()
        close = claw.value_for(0.0)
        width = 0.0
        for _ in range(2):
            q[leader] = close
            q, miss = reach.solve(claw.centre_at(close), target, q, point_along=aim[0], level=aim[1])
            r = reach.pose(q)[:3, :3]
            width = extent(pts, r @ claw.axis)
            close = claw.value_for(width)
        q[leader] = close
        q_grasp, miss = reach.solve(claw.centre_at(close), target, q, point_along=aim[0], level=aim[1])
        r = reach.pose(q_grasp)[:3, :3]
        along = r @ claw.axis, r @ claw.along
        way_in = along[1] if way == "fingers" else np.array([0.0, 0.0, -1.0])
        opened = claw.value_for(min(claw.opening, width + 2 * OPEN_MARGIN))
        q_start = q_grasp.copy()
        q_start[leader] = opened
        q_pre, miss_pre = reach.solve(claw.centre_at(opened), target - approach * way_in,
                                      q_start, point_along=aim[0], level=aim[1])
        residual = max(miss, miss_pre)
        if residual > REACH_TOLERANCE:
            if closest is None or residual < closest[0]:
                closest = (residual, name)
            continue
        found.append(Grasp(name, way, target, q_grasp, q_pre, width, opened, close,
                           residual, float(-along[1][2])))
    found.sort(key=lambda g: -g.down)
    return Candidates(tuple(found), tried, None if closest is None else closest[0],
                      None if closest is None else closest[1])


def _aim(way: str, target: np.ndarray, claw: Claw
         ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray | None]:
    """How an arm that can point its claw points it for ``way`` (:meth:`Reach.solve`'s
    ``point_along`` and ``level``): ``above`` straight down; ``fingers`` level, away from
    the base (the world's origin) towards ``target``, its jaws closing level."""
    if way == "above":
        return (claw.along, np.array([0.0, 0.0, -1.0])), None
    out = np.array([target[0], target[1], 0.0])
    n = float(np.linalg.norm(out))
    out = out / n if n > 1e-9 else np.array([1.0, 0.0, 0.0])
    return (claw.along, out), claw.axis
