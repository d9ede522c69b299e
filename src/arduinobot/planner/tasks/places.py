"""Where things rest and where a place puts them: the supports an object touches (the
pair allowed while a pick lifts it off, and while a place sets it down), the task's
named places (a tasks.yaml's ``places``), the spots on top of a support, and whether a
spot is free.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import fcl
import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.planner.planning.resting import TOUCHING
from arduinobot.planner.tasks.grasps import vertices
from arduinobot.planner.tasks.steps import PlaceTarget
from arduinobot.scene.ground import GROUND_ID
from arduinobot.scene.obstacles import Obstacle
from arduinobot.scene.pose import rpy_of

__all__ = ["TOUCHING", "blocking", "moved", "resolve", "spots", "top", "touching"]

#: the spots tried on a support: its top's centre, then these fractions of the way
#: to its edges (the object's half width kept inside), in eight directions
RINGS = (0.5, 0.9)


def _object(o: Obstacle) -> fcl.CollisionObject:
    t = o.pose()
    return fcl.CollisionObject(o.geometry.collision_geometry(),
                               fcl.Transform(t[:3, :3], t[:3, 3]))


def touching(obj: Obstacle, others: Sequence[Obstacle], *, ground: bool) -> list[str]:
    """The ids of ``others`` (and of the ground, with ``ground``, when the object's
    bottom is on z = 0) within :data:`TOUCHING` of ``obj``."""
    mine = _object(obj)
    out = []
    for o in others:
        if o.id == obj.id:
            continue
        d = fcl.distance(mine, _object(o), fcl.DistanceRequest(), fcl.DistanceResult())
        if d <= TOUCHING:
            out.append(o.id)
    if ground and float(vertices(obj)[:, 2].min()) <= TOUCHING:
        out.append(GROUND_ID)
    return out


def blocking(obj: Obstacle, others: Sequence[Obstacle], support: str | None) -> str | None:
    """The first of ``others`` (not the ``support``) that ``obj`` overlaps, or None."""
    mine = _object(obj)
    for o in others:
        if o.id in (obj.id, support):
            continue
        if fcl.collide(mine, _object(o), fcl.CollisionRequest(), fcl.CollisionResult()):
            return o.id
    return None


def moved(obj: Obstacle, pose: np.ndarray) -> Obstacle:
    """``obj`` posed at ``pose`` (4, 4)."""
    x, y, z = (float(v) for v in pose[:3, 3])
    return replace(obj, xyz=(x, y, z), rpy=rpy_of(pose[:3, :3]))


def resolve(at: PlaceTarget, places: Mapping[str, PlaceTarget],
            obstacles: Sequence[Obstacle], where: str) -> PlaceTarget:
    """A place's ``at`` as a position or an obstacle to put it on: a name is the task's
    place of that name, else the obstacle so named.

    Raises:
        InvalidRequest: a name that is neither (naming both lists); an ``on`` that is
            no obstacle of the scene then.
    """
    ids = [o.id for o in obstacles]
    if at.name is not None:
        if at.name in places:
            at = places[at.name]
        elif at.name in ids:
            at = PlaceTarget(on=at.name)
        else:
            raise InvalidRequest(
                f"'{at.name}' is no place of the task (places: "
                f"{', '.join(places) or 'none'}) and no obstacle (obstacles: "
                f"{', '.join(ids) or 'none'})", field=f"{where}.at")
    if at.on is not None and at.on not in ids:
        raise InvalidRequest(f"no obstacle '{at.on}' to place on (obstacles then: "
                             f"{', '.join(ids) or 'none'})", field=f"{where}.at")
    return at


def spots(support: Obstacle, half_width: float) -> list[np.ndarray]:
    """Candidate (x, y) [m] on ``support``'s top: its centre first, then rings towards
    its edges, each kept ``half_width`` [m] inside them."""
    pts = vertices(support)
    lo, hi = pts[:, :2].min(0), pts[:, :2].max(0)
    centre = (lo + hi) / 2
    room = np.maximum((hi - lo) / 2 - half_width, 0.0)
    out = [centre]
    for f in RINGS:
        for a in np.arange(8) * np.pi / 4:
            d = np.array([np.cos(a), np.sin(a)]) * room * f
            if np.linalg.norm(d) > 1e-6:
                out.append(centre + d)
    return out


def top(support: Obstacle) -> float:
    """[m] the highest point of ``support``."""
    return float(vertices(support)[:, 2].max())
