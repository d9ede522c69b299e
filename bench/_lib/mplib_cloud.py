"""Runs MPlib 0.2.1's point-cloud path on the cloud benchmark's points; JSON in (stdin),
JSON out (the ``output`` file: MPlib's C++ code prints to stdout).

Runs inside .bench-venvs/mplib (MPlib pins numpy 1.x), started by bench/cloud.py through
bench/_lib/mplib_venv.py's venv. Uses only MPlib's own stack: ``mplib.Planner`` on our
expanded URDF and SRDF, ``Planner.update_point_cloud(points, resolution)`` (FCL's OcTree
of the points, MPlib's collision object ``scene_pcd``), and its OMPL RRTConnect
(``planner.planner.plan``, as bench/_lib/mplib_runner.py calls it) with the given budget.

Input: {"urdf", "srdf", "move_group", "points": .npy path (n, 3) float, finite,
"resolution", "repeats", "start": {joint: rad}, "goal": {joint: rad}, "planning_time",
"plans", "output"}. Output: {"update_s": [per repeat], "plan_s": [per plan], "status":
[per plan], "start_valid": bool}.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import time

import mplib
import numpy as np


def main() -> None:
    spec = json.load(sys.stdin)
    points = np.load(spec["points"])
    with contextlib.redirect_stdout(io.StringIO()):
        planner = mplib.Planner(spec["urdf"], spec["move_group"], srdf=spec["srdf"])
    names = list(planner.user_joint_names)
    idx = planner.move_group_joint_indices
    update = []
    for _ in range(spec["repeats"] + 1):  # the first warms MPlib's code paths
        t0 = time.perf_counter()
        planner.update_point_cloud(points, resolution=spec["resolution"])
        update.append(time.perf_counter() - t0)
    full = np.array([spec["start"].get(n, 0.0) for n in names])
    goal = np.array([spec["goal"].get(n, 0.0) for n in names])
    planner.robot.set_qpos(full, True)
    quiet = io.StringIO()
    with contextlib.redirect_stdout(quiet):
        start_valid = len(planner.planning_world.check_collision()) == 0
    plan, status = [], []
    for _ in range(spec["plans"] + 1):  # the first is a warm-up
        planner.robot.set_qpos(full, True)
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(quiet):
            st, _path = planner.planner.plan(full[idx], [goal[idx]],
                                             time=spec["planning_time"], range=0.1,
                                             simplify=True)
        plan.append(time.perf_counter() - t0)
        status.append(st)
    with open(spec["output"], "w") as f:
        json.dump({"update_s": update[1:], "plan_s": plan[1:], "status": status[1:],
                   "start_valid": start_valid}, f)


if __name__ == "__main__":
    main()
