"""MotionBenchMaker-class scenes of our own, seeded: a shelf, a cage, an open box, a table
(obstacles: boxes and cylinders), each placed in front of the arm at a random distance
and yaw, sized to its reach; and problems in them: a goal whose tool point lies inside
the scene's target region (a shelf's middle cell, inside the cage, inside the box, just
over the table among objects), a start whose tool point is outside the scene.

Nothing here is VAMP's or MBM's data: the scene kinds follow MBM's (bookshelf, cage, box,
table_pick), the numbers are ours. Sizes are given for a 0.85 m reach (a Panda) and
scaled by ``reach / 0.85``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from arduinobot.scene.obstacles import Obstacle

KINDS = ("shelf", "cage", "box", "table")
PANDA_REACH = 0.85  # [m] the sizes below are for this reach


@dataclass(frozen=True)
class GenProblem:
    """One generated problem: joint values over the given joints [rad], its obstacles."""

    name: str
    scene: str
    start: tuple[float, ...]
    goal: tuple[float, ...]
    obstacles: tuple[Obstacle, ...]


def _boxes(parts: Sequence[tuple[str, tuple[float, float, float], tuple[float, float, float]]],
           yaw: float, s: float) -> tuple[Obstacle, ...]:
    """(id, local centre, size) in the scene frame (x away from the arm), scaled by ``s``
    and turned by ``yaw`` about the base's z axis."""
    c, si = np.cos(yaw), np.sin(yaw)
    out = []
    for name, (x, y, z), size in parts:
        xyz = (s * (c * x - si * y), s * (si * x + c * y), s * z)
        out.append(Obstacle(name, "box", size=tuple(s * v for v in size), xyz=xyz,
                            rpy=(0.0, 0.0, yaw)))
    return tuple(out)


def scene(kind: str, rng: np.random.Generator, *, reach: float
          ) -> tuple[tuple[Obstacle, ...], tuple[np.ndarray, np.ndarray], float]:
    """Obstacles of one ``kind`` scene, its target region (local lower and upper corner,
    Panda scale) and its yaw [rad]."""
    s = reach / PANDA_REACH
    yaw = float(rng.uniform(-0.6, 0.6))
    d = float(rng.uniform(0.5, 0.62))  # the scene's near face, Panda scale [m]
    t = 0.02  # boards and walls [m]
    if kind == "shelf":
        w, depth, h = float(rng.uniform(0.7, 0.9)), 0.32, float(rng.uniform(0.9, 1.1))
        b = d + depth / 2
        low = float(rng.uniform(0.3, 0.4))  # the middle cell's floor
        cell = float(rng.uniform(0.26, 0.32))
        parts = [("back", (d + depth, 0, h / 2), (t, w, h)),
                 ("side_l", (b, w / 2, h / 2), (depth, t, h)),
                 ("side_r", (b, -w / 2, h / 2), (depth, t, h)),
                 ("board_0", (b, 0, low), (depth, w, t)),
                 ("board_1", (b, 0, low + cell), (depth, w, t)),
                 ("board_top", (b, 0, h), (depth, w, t))]
        target = (np.array([d + 0.06, -w / 2 + 0.12, low + 0.06]),
                  np.array([d + depth - 0.1, w / 2 - 0.12, low + cell - 0.06]))
    elif kind == "cage":
        w, depth, z0, h = 0.6, 0.5, float(rng.uniform(0.15, 0.3)), 0.55
        b = d + depth / 2
        parts = [("base", (b, 0, z0), (depth, w, t)),
                 ("cap", (b, 0, z0 + h), (depth, w, t)),
                 ("back", (d + depth, 0, z0 + h / 2), (t, w, h)),
                 ("side_l", (b, w / 2, z0 + h / 2), (depth, t, h)),
                 ("side_r", (b, -w / 2, z0 + h / 2), (depth, t, h)),
                 ("bar_low", (d, 0, z0 + 0.15), (t, w, t)),
                 ("bar_high", (d, 0, z0 + 0.4), (t, w, t))]
        target = (np.array([d + 0.08, -w / 2 + 0.12, z0 + 0.12]),
                  np.array([d + depth - 0.12, w / 2 - 0.12, z0 + h - 0.12]))
    elif kind == "box":
        w, depth, hw = 0.5, 0.4, float(rng.uniform(0.18, 0.26))
        b = d + depth / 2
        parts = [("base", (b, 0, t / 2), (depth, w, t)),
                 ("wall_near", (d, 0, hw / 2), (t, w, hw)),
                 ("wall_far", (d + depth, 0, hw / 2), (t, w, hw)),
                 ("wall_l", (b, w / 2, hw / 2), (depth, t, hw)),
                 ("wall_r", (b, -w / 2, hw / 2), (depth, t, hw))]
        target = (np.array([d + 0.08, -w / 2 + 0.1, 0.08]),
                  np.array([d + depth - 0.08, w / 2 - 0.1, hw - 0.02]))
    elif kind == "table":
        w, depth, top = 1.0, 0.6, float(rng.uniform(0.3, 0.45))
        b = d + depth / 2
        parts = [("table_top", (b, 0, top), (depth, w, t))]
        parts += [(f"leg_{i}", (b + sx * (depth / 2 - 0.03), sy * (w / 2 - 0.03), top / 2),
                   (0.04, 0.04, top)) for i, (sx, sy) in enumerate(
                       [(1, 1), (1, -1), (-1, 1), (-1, -1)])]
        for i in range(4):  # objects standing on the table
            x, y = float(rng.uniform(d + 0.1, d + depth - 0.1)), float(rng.uniform(-0.4, 0.4))
            hgt = float(rng.uniform(0.1, 0.25))
            parts.append((f"object_{i}", (x, y, top + t / 2 + hgt / 2), (0.05, 0.15, hgt)))
        target = (np.array([d + 0.08, -0.35, top + 0.08]),
                  np.array([d + depth - 0.1, 0.35, top + 0.2]))
    else:
        raise ValueError(f"scene kind {kind!r} unknown (one of {', '.join(KINDS)})")
    return _boxes(parts, yaw, s), (s * target[0], s * target[1]), yaw


def _local(p: np.ndarray, yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([c * p[0] + s * p[1], -s * p[0] + c * p[1], p[2]])


def problems_for(mp: object, joints: Sequence[str], *, n_per_scene: int, seed: int,
                 reach: float, tip: str | None = None, kinds: Sequence[str] = KINDS,
                 fixed: dict[str, float] | None = None, tries: int = 40000
                 ) -> list[GenProblem]:
    """``n_per_scene`` problems of each kind, each in a scene of its own, for the arm of
    ``mp`` (a :class:`~arduinobot.planner.planning.pipeline.MotionPlanner`) over
    ``joints`` (its joint names; others held at ``fixed`` or 0). The tool point is the
    origin of link ``tip`` (default: the last joint's child). Both ends are collision
    free (ground on); the start's tool point is nearer the arm than the scene."""
    d = mp.description  # type: ignore[attr-defined]
    names = tuple(mp.joint_names)  # type: ignore[attr-defined]
    if tuple(joints) != names:
        raise ValueError(f"joints {tuple(joints)} must be the planner's {names}")
    tip = tip or d.robot.joints[names[-1]].child
    lim = d.robot.position_limits(names)
    held = {i: (fixed or {}).get(n) for i, n in enumerate(names) if (fixed or {}).get(n) is not None}
    rng = np.random.default_rng(seed)
    out = []
    for kind in kinds:
        made = 0
        while made < n_per_scene:
            obstacles, (lo, hi), yaw = scene(kind, rng, reach=reach)
            w = mp.world(obstacles)  # type: ignore[attr-defined]
            ends: list[np.ndarray] = []
            for want_inside in (False, True):
                for _ in range(tries):
                    q = rng.uniform(lim[:, 0], lim[:, 1])
                    for i, v in held.items():
                        q[i] = v
                    p = _local(w.kin.link_pose(q, tip)[:3, 3], yaw)
                    inside = bool(np.all(p >= lo) and np.all(p <= hi))
                    outside = p[0] < lo[0] - 0.1 * reach and p[2] > 0.05 * reach
                    if (inside if want_inside else outside) and w.is_valid(q):
                        ends.append(q)
                        break
            if len(ends) < 2:
                continue  # this scene left no room for the tool: draw another
            out.append(GenProblem(f"{kind}#{made}", kind, tuple(map(float, ends[0])),
                                  tuple(map(float, ends[1])), obstacles))
            made += 1
    return out
