"""Task planning time: a pick and place on the course's workspace (its CAD meshes; a
table, a bin with walls and a box on the table: tests/helpers/pick_place.py), planned
as one task in-process, over N seeded variants of the box's and the bin's positions
(each moved up to 4 cm), in two forms: the eleven hand-written steps (above, LIN down
5 cm, close, attach, LIN up, across, down, open, detach, up; the box 2 mm above the
table) and the two steps by name (pick box, place box at bin; the box resting on the
table: grasps generated, candidates tried until one plans whole). Prints each variant's
planning time, then one JSON line per form: the median and largest planning time [s] (a
first, unmeasured task builds the caches), the variants refused (their step and code),
the task's median duration [s] and, by name, the candidates tried (median, most).

Usage: ./dev bench task [N]   (default 20 variants)
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from arduinobot.description import load_description
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.planner.tasks import TaskStepFailed, plan_task, task_from_mapping
from bench._lib.args import problems_per_scene
from bench._lib.report import emit
from tests.helpers.course_workspace import make_course_workspace
from tests.helpers.pick_place import pick_and_place, pick_and_place_by_name, variants


def main() -> None:
    n = problems_per_scene(__doc__ or "", 20)
    with tempfile.TemporaryDirectory(prefix="bench_task_") as tmp:
        ws = make_course_workspace(Path(tmp))
        desc = load_description(ws.xacro, package_dirs=[ws.src],
                                moveit_config=ws.moveit_pkg)
        planner = MotionPlanner(desc)
        plan_task(planner, task_from_mapping(pick_and_place()))  # the caches, unmeasured
        plan_task(planner, task_from_mapping(pick_and_place_by_name()))  # the claw's too
        figures = {form: run(planner, n, by_name=by_name)
                   for form, by_name in (("eleven_steps", False), ("by_name", True))}
    emit("task", figures)


def run(planner: MotionPlanner, n: int, *, by_name: bool) -> dict[str, Any]:
    """Plan the ``n`` variants of one form, print its figures and return them."""
    form = "two steps by name" if by_name else "eleven steps"
    print(f"-- {form}")
    times: list[float] = []
    durations: list[float] = []
    tried: list[int] = []
    failed: list[dict[str, Any]] = []
    for i, body in enumerate(variants(n, by_name=by_name)):
        t0 = time.perf_counter()
        try:
            r = plan_task(planner, task_from_mapping(body))
        except TaskStepFailed as e:
            failed.append({"variant": i, "step": e.index, "code": str(e.code)})
            print(f"variant {i:2d}: step {e.index} failed: {e.message}")
            continue
        dt = time.perf_counter() - t0
        times.append(dt)
        durations.append(r.duration)
        tried.extend(c.tried for c in r.choices if c.kind == "pick")
        chose = "".join(f", {c.kind} {c.name} ({c.tried} of {c.candidates})"
                        for c in r.choices)
        print(f"variant {i:2d}: planned in {dt * 1e3:7.1f} ms, task {r.duration:.2f} s, "
              f"{len(r.steps)} steps{chose}")
    med = statistics.median(times) if times else None
    if med is not None:
        print(f"median planning time {med * 1e3:.1f} ms over {len(times)} variants")
    return {
        "variants": n, "planned": len(times), "failed": failed,
        "median_planning_s": med, "max_planning_s": max(times, default=None),
        "median_task_duration_s": statistics.median(durations) if durations else None,
        **({"median_picks_tried": statistics.median(tried) if tried else None,
            "most_picks_tried": max(tried, default=None)} if by_name else {})}


if __name__ == "__main__":
    main()
