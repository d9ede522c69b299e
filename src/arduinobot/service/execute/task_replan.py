"""A task stopped for a scene change, its remaining steps planned again (``on_change``
``replan``).

The arm came to rest in one of the task's steps (:class:`.task_react.TaskPieces` knows
which, and what the task carried there). :func:`resume_job` builds the ``task`` job
that plans the rest: the task's steps from the one it stopped in, from the stopped
state, with the objects carried there (their poses on their links) and the pairs
touching then (an object still resting on its support: allowed until the lift clears
it), the task's objects where the task had them there (its own; those it moves, whose
kept-scene copies are left out), in the kept scene as it is now. A pick whose object is
already held resumes at the next step (what is left of it is the lift; the next motion
starts from where the arm is), as does a place whose object is already let go. A
``line`` given as an ``offset`` is not resumed from a stop (the offset from there would
end elsewhere): that refusal ends the execution stopped, and says so.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from arduinobot.service.execute.task_react import TaskPieces


def resume_job(task: TaskPieces, at: float, state: Mapping[str, float], *,
               on_change: str) -> tuple[dict[str, Any] | None, str]:
    """The ``task`` job (:func:`arduinobot.service.task.task_service.answer_task`'s data)
    planning the rest of ``task`` after it came to rest at trajectory time ``at`` [s] in
    ``state`` [rad]; or None and why not. The second item says which step it resumes
    at."""
    source = task.replan
    if source is None:
        return None, "the execution names no task to replan"
    i = task.piece_at(at)
    if i is None:
        return None, "it stopped after the task's last motion: nothing is left to plan"
    p = task.pieces[i]
    steps = list(source["task"]["steps"])
    k = int(p["task_step"])
    held = list(p.get("attached") or ())
    carried = {str(a["object"]["id"]) for a in held}
    step = steps[k]
    if ("pick" in step and step["pick"] in carried) \
            or ("place" in step and step["place"] not in carried):
        k += 1  # its object already held (let go): what is left of it is the retreat
    if k >= len(steps):
        return None, "it stopped in the task's last step's retreat: nothing is left to plan"
    line = steps[k].get("line")
    if isinstance(line, Mapping) and "offset" in line:
        return None, (f"step {k} is a line given as an offset: planned from where it "
                      "stopped it would end elsewhere")
    body = {**source["task"], "steps": steps[k:], "start": dict(state),
            "obstacles": list(p.get("obstacles") or ())}
    return {"task": body, "where": source.get("where", "task"), "name": source.get("name"),
            # what it names came back on the wire: no file of this machine
            "start": None, "files": False,
            "trajectories": False, "execute": True,
            "start_tolerance": source.get("start_tolerance", 0.01),
            "move_to_start": False, "on_change": on_change,
            "carrying": held,
            "resting": [list(r) for r in p.get("allowed") or () if r[0] in carried],
            "exclude": list(task.moved), "resumed_at": k, "source": dict(source)
            }, f"step {k}"


def resumed(job: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """The task step a :func:`resume_job` job resumes at, as events name it: its index
    in the task as given and its kind."""
    if job is None:
        return None
    step = job["task"]["steps"][0]
    kind = next((k for k in step if k != "label"), None)
    return {"task_step": int(job["resumed_at"]), "kind": kind}
