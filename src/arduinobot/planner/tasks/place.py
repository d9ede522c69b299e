"""A place step expanded into primitive steps, its spots tried in order until one plans
whole.

The spots: the ``at`` position, or on top of a support (its top's centre, then rings
towards its edges: :func:`arduinobot.planner.tasks.places.spots`), the object's lowest
point on the support's top (no gap). A spot where the object would overlap another
obstacle is taken: skipped (all taken: ``NO_FREE_PLACE`` naming what blocks the first).
A spot becomes: a move above it (``approach`` [m] higher), a straight line down (the
object/support pair allowed: it ends touching), the gripper opened, the detach, and a
straight line back up as far.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from arduinobot.contract.errors import (
    NoFreePlace,
    NoReachableGrasp,
    PlanningError,
)
from arduinobot.planner.tasks.grasps import OPEN_MARGIN, REACH_TOLERANCE
from arduinobot.planner.tasks.pick import all_failed, arm_goal, claw, line_step, reach_of, tcp_at
from arduinobot.planner.tasks.places import blocking, moved, resolve, spots, top
from arduinobot.planner.tasks.steps import DetachStep, GripperStep, MoveStep, PlaceStep

if TYPE_CHECKING:
    from arduinobot.planner.tasks.progress import Part, Progress


def plan_place(progress: Progress, step: PlaceStep, index: int) -> None:
    """Plan ``step`` from where ``progress`` is: the first free spot that plans whole.

    Raises:
        InvalidRequest: the object is not carried; ``at`` names nothing known.
        NoFreePlace: every spot is taken (``details.blocking``).
        NoReachableGrasp: no free spot within the arm's reach (the closest's residual).
        PlanningError: every spot failed to plan (the first one's code).
    """
    p = progress
    planner = p.planner
    where = f"steps[{index}]"
    held = p.attached[p.carried_index(step.object, to="place", field=f"{where}.place")]
    at = resolve(step.at, p.task.places, p.obstacles, where)
    c = claw(planner)
    reach, leader = reach_of(planner, c)
    kin = planner.world(()).kin
    pts = np.asarray(held.shape.geometry.triangles().vertices, float)
    local = held.shape.pose()  # the object in its link's frame
    in_link = pts @ local[:3, :3].T + local[:3, 3]
    centre = (in_link.min(0) + in_link.max(0)) / 2  # link frame

    def world_points(q: np.ndarray) -> np.ndarray:
        t = kin.link_pose(q, held.link)
        return in_link @ t[:3, :3].T + t[:3, 3]

    support = None
    if at.on is not None:
        support = next(o for o in p.obstacles if o.id == at.on)
        half = float(np.max(np.ptp(in_link[:, :2], axis=0))) / 2
        xys = spots(support, half)
        surface = top(support)
    else:
        assert at.position is not None
        xys = [np.asarray(at.position[:2], float)]
    q0 = p.vec()
    free: list[tuple[np.ndarray, np.ndarray, str]] = []
    first_block: str | None = None
    closest: float | None = None
    for n, xy in enumerate(xys):
        z = float(at.position[2]) if at.position is not None else surface
        target = np.array([xy[0], xy[1], z])
        q = q0
        for _ in range(3):  # the object's lowest point on the surface, as held there
            q, miss = reach.solve(centre, target, q)
            if support is not None:
                wp = world_points(q)
                target[2] += surface - float(wp[:, 2].min())
        q, miss = reach.solve(centre, target, q)
        label = "position" if support is None else (
            "centre" if n == 0 else f"spot {n} ({xy[0]:.3f}, {xy[1]:.3f})")
        if miss > REACH_TOLERANCE:
            closest = miss if closest is None else min(closest, miss)
            continue
        pose = kin.link_pose(q, held.link) @ local
        blocked = blocking(moved(held.shape, pose), p.obstacles,
                           None if support is None else support.id)
        if blocked is not None:
            first_block = first_block or blocked
            continue
        q_above, miss_above = reach.solve(centre, target + [0.0, 0.0, step.approach], q)
        if miss_above > REACH_TOLERANCE:
            closest = miss_above if closest is None else min(closest, miss_above)
            continue
        free.append((q, q_above, label))
    if not free:
        if first_block is not None:
            raise NoFreePlace(f"no free spot to place '{held.id}' ({len(xys)} tried): "
                              f"'{first_block}' is in the way", details={
                                  "object": held.id, "blocking": first_block,
                                  "spots": len(xys)})
        raise NoReachableGrasp(f"no spot to place '{held.id}' is within the arm's reach: "
                               f"the closest misses by {closest or 0.0:.3f} m", details={
                                   "object": held.id, "candidates": len(xys),
                                   "closest_residual": round(float(closest or 0.0), 4)})
    gap = float(np.interp(p.q[c.leader], c.values, c.gaps))
    opened = c.value_for(min(c.opening, gap + 2 * OPEN_MARGIN))
    allowed = ((held.id, support.id),) if support is not None else ()
    arm = reach.arm
    failed: list[tuple[str, PlanningError]] = []
    name = step.label or f"place {held.id}"
    for k, (q, q_above, label) in enumerate(free):
        parts: list[Part] = [
            (MoveStep(arm_goal(planner, q_above, arm, f"{where}.place"), options=step.options,
                      label=f"{name}: above"), ()),
            (line_step({"position": tcp_at(planner, q)}, step, f"{name}: down", where),
             allowed),
            (GripperStep(opened, options=step.options, label=f"{name}: release"), allowed),
            (DetachStep(held.id, label=f"{name}: detach"), ()),
            (line_step({"offset": [0.0, 0.0, step.approach]}, step, f"{name}: up",
                   where), ()),
        ]
        snap = p.snapshot()
        try:
            p.run(parts, index)
        except PlanningError as e:
            p.restore(snap)
            failed.append((label, e))
            continue
        from arduinobot.planner.tasks.progress import Choice
        placed = next(o for o in p.obstacles if o.id == held.id)
        p.choices.append(Choice(index, "place", held.id, label, k + 1, len(xys), details={
            "on": None if support is None else support.id,
            "position": [round(float(v), 4) for v in placed.pose()[:3, 3]],
            "failed": [{"candidate": n, "code": str(e.code), "message": e.message}
                       for n, e in failed]}))
        return
    raise all_failed(held.id, "place", failed)
