"""A pick step expanded into primitive steps, its grasp candidates tried in order until
one plans whole (every motion certified and verified, as any step's).

A candidate (:mod:`arduinobot.planner.tasks.grasps`) becomes: the gripper opened a
little wider than the object, a move to the approach's start, a straight line in, the
attach (the fingers its touch links, the step's mass), the gripper closed to the
object's width, and a straight lift. The object rests on its supports
(:func:`arduinobot.planner.tasks.places.touching`): that pair is allowed from the attach
to the end of the lift, and no longer (a lift too short to clear it fails the next step).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

from arduinobot.contract.errors import (
    GoalInCollision,
    InvalidRequest,
    NoReachableGrasp,
    ObjectTooWide,
    PlanningError,
)
from arduinobot.planner.planning.goals import JointGoal, line_from_mapping
from arduinobot.planner.tasks.claw import Claw, claw_of
from arduinobot.planner.tasks.grasps import CLEARANCE, Reach, enumerate_grasps
from arduinobot.planner.tasks.gripper import gripper_group
from arduinobot.planner.tasks.places import touching
from arduinobot.planner.tasks.steps import (
    AttachStep,
    GripperStep,
    MoveStep,
    PickStep,
    Step,
)

if TYPE_CHECKING:
    from arduinobot.planner.tasks.progress import Part, Progress

_CLAWS: weakref.WeakKeyDictionary[Any, Claw] = weakref.WeakKeyDictionary()


def claw(planner: Any) -> Claw:
    """The planner's claw, computed once per planner."""
    found = _CLAWS.get(planner)
    if found is None:
        found = _CLAWS[planner] = claw_of(planner)
    return found


def reach_of(planner: Any, c: Claw) -> tuple[Reach, int]:
    """Solving the arm joints for a point of the claw's link; the leader's index."""
    names = list(planner.joint_names)
    desc = planner.description
    grip = set(desc.group_joints().get(gripper_group(desc), []))
    lim = planner.limits(1.0, 1.0)
    arm = [i for i, n in enumerate(names) if n not in grip]
    return (Reach(planner.world(()).kin, c.link, arm, np.asarray(lim.lower, float),
                  np.asarray(lim.upper, float)), names.index(c.leader))


def tcp_at(planner: Any, q: np.ndarray) -> list[float]:
    """[m] the robot's tool point at ``q`` (what a line's ``position`` moves)."""
    tcp = planner.description.tcp
    if tcp is None:
        raise InvalidRequest("a pick or place moves in straight lines: the model needs a "
                             "tool point (tcp)", field="tcp")
    t = planner.world(()).kin.link_pose(q, tcp.parent_link)
    return [float(v) for v in t[:3, :3] @ np.asarray(tcp.xyz, float) + t[:3, 3]]


def arm_goal(planner: Any, q: np.ndarray, arm: list[int], where: str) -> JointGoal:
    names = planner.joint_names
    return JointGoal({names[i]: float(q[i]) for i in arm}, where=where)


def plan_pick(progress: Progress, step: PickStep, index: int) -> None:
    """Plan ``step`` from where ``progress`` is: the first candidate that plans whole.

    Raises:
        NoReachableGrasp: no candidate within reach (the closest one's residual).
        ObjectTooWide: every reachable one wider than the claw opens (both widths).
        PlanningError: every candidate failed to plan; the first one's code, each
            candidate's error in ``details.candidates``.
    """
    p = progress
    planner = p.planner
    where = f"steps[{index}]"
    obj = p.obstacles[p.obstacle_index(step.object, to="pick", field=f"{where}.pick")]
    c = claw(planner)
    reach, leader = reach_of(planner, c)
    found = enumerate_grasps(c, reach, obj, p.vec(), approach=step.approach, leader=leader,
                             hints=dict(step.grasp))
    if not found.reachable:
        raise NoReachableGrasp(
            f"no grasp of '{obj.id}' is within the arm's reach: the closest of "
            f"{found.tried} candidates ({found.closest_name}) misses by "
            f"{found.closest_residual:.3f} m", details={
                "object": obj.id, "candidates": found.tried,
                "closest_residual": round(float(found.closest_residual or 0.0), 4),
                "closest": found.closest_name})
    fits = [g for g in found.reachable if g.width + 2 * CLEARANCE <= c.opening]
    if not fits:
        width = min(g.width for g in found.reachable)
        raise ObjectTooWide(
            f"'{obj.id}' is {width:.3f} m wide between the fingers; the claw opens "
            f"{c.opening:.3f} m at its tips ({2 * CLEARANCE:.3f} m of it kept clear)",
            details={"object": obj.id, "width": round(width, 4),
                     "opening": round(c.opening, 4), "clearance": 2 * CLEARANCE})
    supports = touching(obj, p.obstacles, ground=p.task.ground)
    allowed = tuple((obj.id, s) for s in supports)
    arm = reach.arm
    failed: list[tuple[str, PlanningError]] = []
    world = planner.world(tuple(p.obstacles), tuple(p.attached), p.task.clouds,
                          ground=p.task.ground)
    for k, g in enumerate(fits):
        name = step.label or f"pick {obj.id}"
        q_in = g.q_grasp.copy()
        q_in[leader] = g.open
        # a candidate whose claw, open, is in something where it would close is not
        # planned at all (milliseconds, not a planned approach refused at its end)
        chk = world.check(q_in)
        if not chk.valid:
            failed.append((g.name, GoalInCollision(
                "the claw, open at the grasp, collides",
                pairs=chk.pairs, q=dict(zip(planner.joint_names, map(float, q_in))))))
            continue
        parts: list[Part] = [
            (GripperStep(g.open, options=step.options, label=f"{name}: open"), ()),
            (MoveStep(arm_goal(planner, g.q_pre, arm, f"{where}.pick"),
                      options=step.options, label=f"{name}: approach"), ()),
            (line_step({"position": tcp_at(planner, q_in)}, step, f"{name}: in",
                   where), ()),
            (AttachStep(obj.id, link=c.link, mass=step.mass, touch_links=c.fingers,
                        label=f"{name}: attach"), ()),
            (GripperStep(g.close, options=step.options, label=f"{name}: grip"), allowed),
            (line_step({"offset": [0.0, 0.0, step.lift]}, step, f"{name}: lift",
                   where), allowed),
        ]
        snap = p.snapshot()
        try:
            p.run(parts, index)
        except PlanningError as e:
            p.restore(snap)
            failed.append((g.name, e))
            continue
        from arduinobot.planner.tasks.progress import Choice
        p.choices.append(Choice(index, "pick", obj.id, g.name, k + 1, len(fits), details={
            "width": round(g.width, 4), "opening": round(c.opening, 4),
            "target": [round(float(v), 4) for v in g.target], "supports": supports,
            "failed": [{"candidate": n, "code": str(e.code), "message": e.message}
                       for n, e in failed]}))
        return
    raise all_failed(obj.id, "pick", failed)


def line_step(data: dict[str, Any], step: Any, label: str, where: str) -> Step:
    """A straight tcp move (``position`` or ``offset``) with ``step``'s options."""
    return MoveStep(line_from_mapping(data, f"{where}.{step.kind}"), options=step.options,
                    label=label)


def all_failed(obj: str, kind: str, failed: list[tuple[str, PlanningError]]
                ) -> PlanningError:
    """Every candidate failed: the first one's error (its code), each one's listed."""
    first = failed[0][1]
    err = PlanningError(
        f"none of {len(failed)} candidates to {kind} '{obj}' planned whole; the first "
        f"({failed[0][0]}): {first.message}", details={
            "object": obj, **dict(first.details),
            "candidates": [{"candidate": n, "code": str(e.code), "message": e.message}
                           for n, e in failed]})
    err.code = first.code
    return err
