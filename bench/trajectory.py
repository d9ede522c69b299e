"""Trajectory benchmark: time parameterisation + verification per scene; JSON line at the end.

Scenes and problems are bench/planning.py's. Per problem: plan once, then time the path
with ruckig (jerk-limited) and toppra (time-optimal), each verified; report the compute
time of parameterise+verify, the jerk-limited / time-optimal duration ratio, and the
violations an independent re-check finds: finite differences of positions evaluated
on a fine grid (velocity, acceleration, jerk), torques at those finite-difference
derivatives, and a dense collision check by linear interpolation between fine states.

MPlib comparison: not run yet (see ``MPLIB``): the wheel (mplib 0.2.1, cp311) installs
into .bench-venvs/mplib, but the runner that loads our URDF/SRDF into it is not written.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from planning import SCENES, problems  # noqa: E402

from description import load_description  # noqa: E402
from planner.curve import build_curve  # noqa: E402
from planner.errors import PlanningError  # noqa: E402
from planner.goals import JointGoal  # noqa: E402
from planner.motion_check import interpolate  # noqa: E402
from planner.pipeline import MotionPlanner  # noqa: E402
from planner.planning import PathRequest  # noqa: E402

MPLIB = {"status": "not run", "reason": "runner for our URDF/SRDF in .bench-venvs/mplib "
         "not written yet (mplib-0.2.1-cp311 wheel downloads and installs)"}


def independent_violations(traj, limits, dynamics, world, *, dt: float = 5e-4) -> int:
    """Count violated limit kinds found by re-deriving everything from positions."""
    ts = np.arange(0.0, traj.duration, dt)
    ts = np.append(ts, traj.duration)
    q = traj.evaluate(ts)[0]
    h = np.diff(ts)
    v = np.diff(q, axis=0) / h[:, None]
    a = np.diff(v, axis=0) / (0.5 * (h[1:] + h[:-1]))[:, None]
    j = np.diff(a, axis=0) / h[1:-1, None]
    tol = 1.02  # finite differences of a smooth curve at 0.5 ms: ~1 % discretisation error
    bad = 0
    bad += bool(np.any(q < limits.lower - 1e-9) or np.any(q > limits.upper + 1e-9))
    bad += bool(np.any(np.abs(v) > limits.velocity * tol))
    bad += bool(np.any(np.abs(a) > limits.acceleration * tol))
    if traj.profile == "jerk_limited":
        bad += bool(np.any(np.abs(j) > limits.jerk * tol))
    tau = dynamics.torques_batch(q[1:-1], 0.5 * (v[1:] + v[:-1]), a)
    bad += bool(np.any(np.abs(tau) > limits.effort * tol))
    bad += world.first_invalid(interpolate(q, 0.002)) >= 0
    return bad


def main(n: int = 10) -> None:
    d = load_description()
    mp = MotionPlanner(d)
    summary: dict[str, dict] = {}
    for scene, obs in SCENES.items():
        obs = tuple(obs)
        world = mp.world(obs)
        _, paths = mp._entry(obs)
        limits = mp.limits(1.0, 1.0)
        rng = np.random.default_rng(7)
        compute = {"jerk_limited": [], "time_optimal": []}
        ratios, violations, fails = [], 0, 0
        for i, (a, b, _) in enumerate(problems(world, n, rng)):
            try:
                res = paths.solve(PathRequest(start=a, goal=JointGoal(
                    dict(zip(world.kin.joint_names[:3], map(float, b[:3])))),
                    planning_time=2.0, seed=i))
            except PlanningError:
                fails += 1
                continue
            curve = build_curve(res.path, world)
            dur = {}
            for prof in ("jerk_limited", "time_optimal"):
                t0 = time.perf_counter()
                traj, rep, _, _ = mp.time_path(curve, res.path, world, limits, profile=prof)
                compute[prof].append(time.perf_counter() - t0)
                dur[prof] = traj.duration
                violations += independent_violations(traj, limits, mp.dynamics, world)
            ratios.append(dur["jerk_limited"] / dur["time_optimal"])
        row = {
            "problems": n, "plan_failures": fails,
            "ruckig_param_verify_ms_median": 1e3 * statistics.median(compute["jerk_limited"]),
            "toppra_param_verify_ms_median": 1e3 * statistics.median(compute["time_optimal"]),
            "duration_ratio_median": statistics.median(ratios),
            "duration_ratio_max": max(ratios),
            "independent_violations": violations,
        }
        summary[scene] = row
        print(scene, {k: round(v, 3) if isinstance(v, float) else v for k, v in row.items()})
    summary["mplib"] = MPLIB
    print(json.dumps(summary))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
