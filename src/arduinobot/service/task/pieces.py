"""A task's joined motion cut into its steps' worlds, for re-checking it while it runs.

A task changes its world along its own motion: an attach makes an obstacle part of the
arm, a detach puts it back where it then is, an object resting on its support may touch
it until the lift clears it. So the rest of a running task is not checked in one scene
(as a single motion's is): each step's piece of the joined trajectory is checked in the
world that step was planned in, with the kept scene as it is now. :func:`task_pieces`
gives, from the planned :class:`~arduinobot.planner.tasks.TaskResult` (each
:class:`~arduinobot.planner.tasks.StepResult` records its carried objects, the scene as
the task had it there and the allowed pairs), the execute request's ``task`` section:
one piece per step that lasts (a motion, a wait), with its time span in the joined
trajectory [s], its step (index, kind, label, and the task's own step it belongs to),
its carried objects (posed on their links), the allowed pairs, and the task's obstacles
that the kept scene does not give: the task's own, and those the task moves (picked,
placed; their kept-scene copy is left out: ``moved``). The execute wing
(:mod:`arduinobot.service.execute.task_react`) samples each piece's rest and a worker
certifies it (:mod:`arduinobot.service.plan.task_recheck`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from arduinobot.planner.tasks import Task, TaskResult


def task_pieces(task: Task, result: TaskResult, *, scene_ids: Sequence[str] = (),
                moved: Sequence[str] = (), first: int = 0) -> dict[str, Any]:
    """The execute request's ``task`` section (see the module doc) of ``result``, planned
    for ``task`` in a kept scene holding the obstacles ``scene_ids``; ``moved``: objects
    the task moved before (a task's rest replanned: also its carried ones), ``first``:
    the index of ``task``'s first step in the task as the user gave it."""
    kept = set(scene_ids)
    moved = sorted({s.object for s in result.steps
                    if s.kind in ("attach", "detach") and s.object is not None}
                   | {a.id for a in task.carrying} | set(moved))
    pieces = []
    for s, t0 in zip(result.steps, result.boundaries()):
        if s.duration <= 0.0:
            continue  # an attach, a detach: no motion of its own (the next piece's world)
        own = s.part_of if s.part_of is not None else s.index
        sent = [o for o in s.obstacles if o.id not in kept or o.id in moved]
        if not all(o.geometry.portable for o in (*sent, *(a.shape for a in s.attached))):
            # a mesh read from a file of this machine: what comes back on the wire may
            # not name files (the check refuses them), so this task is not re-checked
            return {"name": task.name, "ground": bool(task.ground), "pieces": [],
                    "unchecked": f"step {own}'s world has a mesh read from a file of the "
                    "server (a task's own mesh obstacle): its rest is not re-checked"}
        pieces.append({
            "step": s.index, "kind": s.kind, "label": s.label,
            "task_step": own + first, "task_kind": task.steps[own].kind,
            "start": t0, "end": t0 + s.duration,
            "obstacles": [o.to_json() for o in sent],
            "attached": [a.to_mapping() for a in s.attached],
            "allowed": [list(p) for p in s.allowed]})
    return {"name": task.name, "ground": bool(task.ground),
            "moved": [m for m in moved if m in kept], "pieces": pieces}
