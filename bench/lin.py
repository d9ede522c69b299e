"""Straight-line moves (LIN) on the course model: planning time median / p95.

The course-like workspace (tests/helpers/course_workspace.py: CAD meshes, a MoveIt
package with pilz_cartesian_limits.yaml and default scaling 0.1), N seeded problems: a
collision-free start of the arm, a line of 2 to 10 cm in a random direction (world
frame). Each is planned in-process through the whole pipeline (dense IK, certification,
timing within the Cartesian and joint limits, verification). Prints, then one JSON
line: planning time of the lines planned (median / p95 ms, the first excluded: it builds
the caches), how many were refused (LINE_INTERRUPTED, by reason) and the largest tcp
deviation from a line [mm].

Usage: ./dev bench lin [N]   (default 40 problems)
"""

from __future__ import annotations

import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from arduinobot.contract.errors import LineInterrupted
from arduinobot.description import load_description
from arduinobot.planner.planning.goals import LineGoal
from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
from bench._lib.args import problems_per_scene
from bench._lib.report import emit
from tests.helpers.course_workspace import make_course_workspace

ARM = ("joint_1", "joint_2", "joint_3")


def main() -> None:
    n = problems_per_scene(__doc__, 40)
    with tempfile.TemporaryDirectory() as tmp:
        ws = make_course_workspace(Path(tmp))
        d = load_description(ws.xacro, package_dirs=[ws.src], env={})
        mp = MotionPlanner(d)
        world = mp.world(())
        rng = np.random.default_rng(2029)
        lim = d.robot.position_limits(ARM)
        times, devs, refused = [], [], Counter()
        for k in range(n + 1):
            while True:  # a collision-free start of the arm
                q = rng.uniform(0.8 * lim[:, 0], 0.8 * lim[:, 1])
                full = np.zeros(len(mp.joint_names))
                full[:3] = q
                if world.check(full).valid:
                    break
            u = rng.normal(size=3)
            off = rng.uniform(0.02, 0.10) * u / np.linalg.norm(u)
            req = MotionRequest(goal=LineGoal(offset=tuple(off)),
                                start=dict(zip(ARM, map(float, q))))
            t0 = time.perf_counter()
            try:
                res = mp.solve(req)
            except LineInterrupted as e:
                refused[e.reason] += 1
                continue
            dt = time.perf_counter() - t0
            if k == 0:
                continue  # the first builds the caches
            times.append(1e3 * dt)
            devs.append(1e3 * res.line.max_deviation)
        med = float(np.median(times)) if times else float("nan")
        p95 = float(np.percentile(times, 95)) if times else float("nan")
        print(f"LIN on the course model: {len(times)} lines planned, "
              f"{sum(refused.values())} refused {dict(refused)}")
        print(f"planning time median {med:.1f} ms, p95 {p95:.1f} ms; largest deviation "
              f"{max(devs, default=float('nan')):.4f} mm")
        emit("lin", {"problems": n, "planned": len(times), "refused": dict(refused),
                     "median_ms": med, "p95_ms": p95,
                     "max_deviation_mm": max(devs, default=float("nan"))})


if __name__ == "__main__":
    main()
