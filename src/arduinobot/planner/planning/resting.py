"""A carried object that starts resting on something: lifted off by a straight line only.

An object attached where it lies on a support (a cup on a table, a box on the ground)
touches it: every state of the start collides on that pair, so no motion could leave
it. :func:`resting_pairs` finds, at a request's start, each (carried object, obstacle)
pair that collides and is only *touching*: the object is no deeper than
:data:`TOUCHING` in the obstacle (it misses the obstacle shrunk by that much). Boxes,
cylinders and spheres can be shrunk exactly; a mesh obstacle cannot, so an object in
contact with one is never taken to rest on it.

:func:`lift_off` is what :class:`~arduinobot.planner.planning.pipeline.MotionPlanner`
does with such a start (the door, for the service's plan path and a library user
alike):

- A straight line (``line``) from rest is planned with the pair allowed, and with the
  support's *core* (the support shrunk by :data:`DEPTH`, an extra obstacle checked
  against that object only) in the world: the line's certificate then proves the object
  never goes deeper than :data:`DEPTH` into its support anywhere along the motion, so it
  cannot be dragged or pushed through it. The line must end with the object clear of
  the support (further than :data:`TOUCHING`, checked at the end state without the
  allowance), else :class:`~arduinobot.contract.errors.GoalInCollision` names the pair.
- Any other goal (or a moving start) is refused
  :class:`~arduinobot.contract.errors.StartInCollision` with a hint (``details.resting``,
  ``details.hint``): lift it first.

A request that allows a pair itself (``allowed``: a task's pick and place, which track
their resting pairs step by step) is left as it is for that pair.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import fcl
import numpy as np

from arduinobot.contract.errors import GoalInCollision, InvalidRequest, StartInCollision
from arduinobot.planner.planning.goals import LineGoal
from arduinobot.planner.planning.motion import MotionRequest, MotionResult
from arduinobot.planner.planning.strategy import moves_at_start
from arduinobot.scene.ground import with_ground
from arduinobot.scene.obstacles import AttachedObject, Obstacle
from arduinobot.scene.pose import rpy_of

if TYPE_CHECKING:  # annotations only: the context imports the heavy stack
    from arduinobot.planner.kinematics.chain import Kinematics
    from arduinobot.planner.planning.context import PlanningContext

__all__ = ["DEPTH", "TOUCHING", "Lift", "cores_for", "lift_off", "lifting_world",
           "resting_pairs"]

#: [m] an object this close to another rests on it (touches it); and the deepest it may
#: be in it at the start to count as resting, not stuck in it
TOUCHING = 1e-3
#: [m] the deepest a lifted object may go into its support along the line: the support
#: shrunk by this much (its core) is checked against the object on the whole motion
DEPTH = 2 * TOUCHING
#: what the hint suggests: 5 cm straight up
HINT_LINE = {"line": {"offset": [0, 0, 0.05]}}


def _fcl(geometry: object, pose: np.ndarray) -> fcl.CollisionObject:
    return fcl.CollisionObject(geometry.collision_geometry(),  # type: ignore[attr-defined]
                               fcl.Transform(pose[:3, :3], pose[:3, 3]))


def core(support: Obstacle, depth: float = DEPTH) -> Obstacle | None:
    """``support`` shrunk by ``depth`` [m] on every side (same pose; the id
    ``<id>.core``), or None when its shape cannot be shrunk exactly (a mesh) or
    vanishes."""
    try:
        shrunk = support.geometry.grown(-depth)
    except InvalidRequest:  # a mesh, or thinner than twice the depth
        return None
    return replace(support, id=f"{support.id}.core", geometry=shrunk)


def _named(c: Obstacle, taken: set[str]) -> Obstacle:
    # a core's id clear of the request's own (a scene may hold a "table.core" already)
    name = c.id
    while name in taken:
        name += "_"
    return c if name == c.id else replace(c, id=name)


def carried_pose(kin: Kinematics, a: AttachedObject, q: np.ndarray) -> np.ndarray:
    """Where carried object ``a`` is at joints ``q`` [rad]: its world pose (4, 4)."""
    return kin.link_pose(q, a.link) @ a.shape.pose()


def placed(a: AttachedObject, pose: np.ndarray) -> Obstacle:
    """Carried object ``a`` as a free obstacle at world ``pose`` (4, 4)."""
    x, y, z = (float(v) for v in pose[:3, 3])
    return replace(a.shape, xyz=(x, y, z), rpy=rpy_of(pose[:3, :3]))


def gap(a: Obstacle, b: Obstacle) -> float:
    """[m] the distance between two obstacles (0 or less when they touch)."""
    return float(fcl.distance(_fcl(a.geometry, a.pose()), _fcl(b.geometry, b.pose()),
                              fcl.DistanceRequest(), fcl.DistanceResult()))


def overlaps(a: Obstacle, b: Obstacle) -> bool:
    """Whether two obstacles overlap."""
    return bool(fcl.collide(_fcl(a.geometry, a.pose()), _fcl(b.geometry, b.pose()),
                            fcl.CollisionRequest(), fcl.CollisionResult()))


def resting_pairs(kin: Kinematics, attached: Sequence[AttachedObject],
                  obstacles: Sequence[Obstacle], pairs: Sequence[tuple[str, str]],
                  q: np.ndarray) -> tuple[tuple[str, str], ...]:
    """Of the colliding ``pairs`` at joints ``q`` [rad] (a world check's), the
    (carried object, obstacle) ones where the object only touches the obstacle: no
    deeper in it than :data:`TOUCHING` (it misses the obstacle's core at that depth).
    ``obstacles``: the request's, with the ground if it has one."""
    carried = {a.id: a for a in attached}
    by_id = {o.id: o for o in obstacles}
    out: list[tuple[str, str]] = []
    for x, y in pairs:
        obj, sup = (x, y) if x in carried else (y, x)
        if obj not in carried or sup not in by_id:
            continue
        inner = core(by_id[sup], TOUCHING)
        if inner is None:
            continue
        here = placed(carried[obj], carried_pose(kin, carried[obj], q))
        if not overlaps(here, inner):
            out.append((obj, sup))
    return tuple(sorted(set(out)))


def hint(pairs: Sequence[tuple[str, str]]) -> str:
    """What a refusal says to do about resting ``pairs``."""
    rest = ", ".join(f"'{o}' rests on '{s}'" for o, s in pairs)
    return (f"{rest}: lift it first with a straight line, e.g. "
            f"{json.dumps(HINT_LINE)}")


@dataclass(frozen=True)
class Lift:
    """A line that lifts carried objects off what they rest on: the ``request`` to plan
    (the pairs allowed, the supports' cores added) and the ``pairs`` to be clear of at
    its end."""

    request: MotionRequest
    pairs: tuple[tuple[str, str], ...]

    def check_end(self, context: PlanningContext, result: MotionResult) -> None:
        """Refuse ``result`` unless every lifted object ends further than
        :data:`TOUCHING` from its support.

        Raises:
            GoalInCollision: naming the pairs still touching at the line's end.
        """
        req = self.request
        q = np.asarray(result.trajectory.positions[-1], float)
        kin = context.kin
        carried = {a.id: a for a in req.attached}
        by_id = {o.id: o for o in with_ground(req.obstacles, req.ground)}
        still = [(o, s) for o, s in self.pairs
                 if gap(placed(carried[o], carried_pose(kin, carried[o], q)),
                        by_id[s]) <= TOUCHING]
        if still:
            named = ", ".join(f"'{o}' still on '{s}'" for o, s in still)
            raise GoalInCollision(
                f"the line ends with {named} (within {TOUCHING * 1e3:g} mm): lift it "
                f"clear with a straight line away from it, e.g. {json.dumps(HINT_LINE)}",
                pairs=still, q=dict(zip(context.joint_names, map(float, q))))


def cores_for(pairs: Sequence[tuple[str, str]], obstacles: Sequence[Obstacle],
              attached: Sequence[AttachedObject], links: Sequence[str]
              ) -> tuple[tuple[Obstacle, ...], tuple[tuple[str, str], ...]] | None:
    """The supports' cores (ids clear of ``obstacles`` and ``attached``) and the pairs to
    allow while the objects of ``pairs`` are lifted off: those pairs, and every body but
    the lifted objects against the cores (each core lies inside its support, which keeps
    them off it). None when a support has no core (a mesh, or too thin)."""
    by_id = {o.id: o for o in obstacles}
    cores = {s: core(by_id[s]) for _, s in pairs}
    if any(c is None for c in cores.values()):
        return None
    taken = {o.id for o in obstacles} | {a.id for a in attached}
    added = tuple(_named(c, taken) for c in cores.values() if c is not None)
    objects = {o for o, _ in pairs}
    others = list(links) + [a.id for a in attached if a.id not in objects]
    return added, (*pairs, *((n, c.id) for c in added for n in others))


def lifting_world(kin: Kinematics, attached: Sequence[AttachedObject],
                  obstacles: Sequence[Obstacle], pairs: Sequence[tuple[str, str]],
                  first: np.ndarray, last: np.ndarray
                  ) -> tuple[tuple[Obstacle, ...], tuple[tuple[str, str], ...]] | None:
    """For a motion from ``first`` to ``last`` [rad] (a running lift's rest): the cores
    and allowed pairs (:func:`cores_for`) when carried objects rest on something at
    ``first`` (of the colliding ``pairs`` there) and every one ends clear of it at
    ``last`` (further than :data:`TOUCHING`); else None."""
    resting = resting_pairs(kin, attached, obstacles, pairs, first)
    if not resting:
        return None
    carried = {a.id: a for a in attached}
    by_id = {o.id: o for o in obstacles}
    if any(gap(placed(carried[o], carried_pose(kin, carried[o], last)), by_id[s])
           <= TOUCHING for o, s in resting):
        return None
    return cores_for(resting, obstacles, attached, kin.link_names)


def lift_off(context: PlanningContext, request: MotionRequest) -> Lift | None:
    """What to plan for ``request`` whose carried objects may rest on something at its
    start (see the module doc): None when none does (plan it as it is).

    Raises:
        StartInCollision: an object rests on something and the goal is no straight
            line from rest (``details.resting``: the pairs; ``details.hint``).
    """
    if not request.attached:
        return None
    start = context.validate(request)
    world = context.world(request.obstacles, request.attached, request.clouds,
                          ground=request.ground, allowed=request.allowed)
    chk = world.check(start)
    if chk.valid:
        return None
    obstacles = with_ground(request.obstacles, request.ground)
    pairs = resting_pairs(world.kin, request.attached, obstacles, chk.pairs, start)
    if not pairs:
        return None  # collides otherwise: the strategy says so
    q = dict(zip(context.joint_names, map(float, start)))
    if not isinstance(request.goal, LineGoal) or moves_at_start(request):
        err = StartInCollision(f"the start state collides ({hint(pairs)})",
                               pairs=chk.pairs, q=q)
        err.details.update({"resting": [list(p) for p in pairs], "hint": hint(pairs)})
        raise err
    found = cores_for(pairs, obstacles, request.attached, world.bodies.names)
    if found is None:  # a mesh, or thinner than twice DEPTH: nothing to prove it against
        raise StartInCollision(
            f"the start state collides: {', '.join(repr(s) for _, s in pairs)} has no "
            f"core to prove the lift against (a mesh, or {2 * DEPTH * 1e3:g} mm thin or "
            f"less)", pairs=chk.pairs, q=q)
    added, allowed = found
    return Lift(replace(request, obstacles=(*request.obstacles, *added),
                        allowed=(*request.allowed, *allowed)), pairs)
