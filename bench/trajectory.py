"""Trajectory benchmark, ours vs MPlib on the same problems; figures, then one JSON line.

Per scene (bench/_lib/scenes.py, the planning benchmark's scenes and seeded problems):

- ours end to end: ``MotionPlanner.solve`` (validate, plan, blend, jerk-limited timing,
  verification), wall clock, RRTConnect with a 1 s budget;
- param+verify: on each planned path, ``time_path`` with ruckig (jerk-limited) and with
  toppra (time-optimal), each verified, timed; and the jerk-limited duration over the
  time-optimal one;
- MPlib 0.2.1 (OMPL RRTConnect, FCL, TOPP-RA: the peer with our stack) in its own venv
  (.bench-venvs/mplib, created on demand) through bench/_lib/mplib_runner.py, on the same
  problems with the same budget and our velocity/acceleration limits: plan + TOPP time;
- violations in every returned trajectory, both ours and MPlib's, by our verifier
  (arduinobot.planner.timing.verify.Verifier) and by the independent re-check (bench/_lib/recheck.py).
  MPlib's trajectories are rebuilt from its toppra data (checked against its samples).

Both sides get one warm-up problem per scene that is not counted. Usage:
``./dev bench trajectory [problems per scene]`` (default 8).
"""

from __future__ import annotations

import multiprocessing as mp_
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from arduinobot.contract.errors import PlanningError
from arduinobot.description import load_description
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
from arduinobot.planner.timing.curve import build_curve
from arduinobot.planner.timing.trajectory import JointTrajectory
from arduinobot.planner.timing.verify import Verifier
from bench._lib.args import problems_per_scene
from bench._lib.mplib_venv import MplibTiming, mplib_python, run_mplib
from bench._lib.recheck import IndependentModel, Limits, recheck
from bench._lib.report import emit
from bench._lib.scenes import SCENES, obstacle_dicts, problems, write_model

PLANNING_TIME = 1.0
ARM = ("joint_1", "joint_2", "joint_3")


def stats(xs: list[float]) -> dict:
    if not xs:
        return {"median_ms": None, "p95_ms": None}
    return {"median_ms": 1e3 * statistics.median(xs), "p95_ms": 1e3 * float(np.percentile(xs, 95))}


# re-check tasks, read by forked workers (no pickling of trajectories)
TASKS: list[tuple] = []
MODEL_FILES: tuple = ()


def _recheck_task(i: int):
    global _MODEL
    if "_MODEL" not in globals():
        _MODEL = IndependentModel(*MODEL_FILES)
    positions, duration, limits, obstacles, jerk = TASKS[i]
    return recheck(_MODEL, positions, duration, limits, obstacles=obstacles,
                   enforce_jerk=jerk)


def main(n: int = 8) -> None:
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    set_ompl_log_level("none")
    global MODEL_FILES
    d = load_description()
    mp = MotionPlanner(d)
    names = mp.joint_names
    lim = mp.limits(1.0, 1.0)
    rl = Limits(*(np.asarray(getattr(lim, k), float) for k in
                  ("lower", "upper", "velocity", "acceleration", "jerk", "effort")))
    tmp = Path(tempfile.mkdtemp(prefix="bench-trajectory-"))
    urdf, srdf = write_model(tmp / "model")
    MODEL_FILES = (urdf, srdf, names)
    rows: dict[str, dict] = {}
    spec = {"urdf": str(urdf), "srdf": str(srdf), "move_group": "claw_support",
            "velocity": [float(lim.velocity[names.index(j)]) for j in ARM],
            "acceleration": [float(lim.acceleration[names.index(j)]) for j in ARM],
            "time_step": 0.01, "warmup": True, "output": str(tmp / "mplib.json"),
            "scenes": {}}
    probs_of: dict[str, list] = {}
    recheck_of: dict[str, list] = {}  # scene -> [(kind, task index)]
    for scene, obs in SCENES.items():
        obs = tuple(obs)
        world = mp.world(obs)
        probs = problems(world, n, np.random.default_rng(7))
        probs_of[scene] = probs
        spec["scenes"][scene] = {"obstacles": obstacle_dicts(list(obs)), "problems": [
            {"start": dict(zip(names, map(float, a))), "goal": dict(zip(ARM, map(float, b[:3]))),
             "planning_time": PLANNING_TIME} for a, b, _ in probs]}

        def request(i: int, a: np.ndarray, b: np.ndarray,
                    obs: tuple = obs) -> MotionRequest:
            return MotionRequest(goal=JointGoal(dict(zip(ARM, map(float, b[:3])))),
                                 start=dict(zip(names, map(float, a))), obstacles=obs,
                                 planning_time=PLANNING_TIME, seed=i)

        try:  # warm-up, not counted
            mp.solve(request(0, *probs[0][:2]))
        except PlanningError:
            pass
        e2e, ok, compute, ratios, ours_verifier_bad, tasks = [], 0, {"jerk_limited": [],
                                                                   "time_optimal": []}, [], 0, []
        at_mismatch = 0.0
        for i, (a, b, _) in enumerate(probs):
            t0 = time.perf_counter()
            try:
                res = mp.solve(request(i, a, b))
            except PlanningError:
                e2e.append(time.perf_counter() - t0)
                continue
            e2e.append(time.perf_counter() - t0)
            ok += 1
            ours_verifier_bad += not res.verification.ok
            curve = build_curve(res.path, world)
            dur = {}
            for prof in ("jerk_limited", "time_optimal"):
                t1 = time.perf_counter()
                try:
                    traj, rep, _, _ = mp.time_path(curve, res.path, world, lim, profile=prof)
                except PlanningError:
                    compute[prof].append(time.perf_counter() - t1)
                    continue
                compute[prof].append(time.perf_counter() - t1)
                dur[prof] = traj.duration
                ours_verifier_bad += not rep.ok
                # the re-check reads positions through evaluate(), the vectorised at(t)
                for t in np.random.default_rng(i).uniform(0, traj.duration, 5):
                    at_mismatch = max(at_mismatch, float(np.max(np.abs(
                        np.array(traj.at(float(t)).positions) - traj.evaluate([t])[0][0]))))
                TASKS.append((lambda ts, tr=traj: tr.evaluate(ts)[0], traj.duration, rl,
                              obstacle_dicts(list(obs)), prof == "jerk_limited"))
                tasks.append((prof, len(TASKS) - 1))
            if len(dur) == 2:
                ratios.append(dur["jerk_limited"] / dur["time_optimal"])
        recheck_of[scene] = tasks
        rows[scene] = {
            "problems": n,
            "ours": {"success": ok / n, **stats(e2e),
                     "verifier_violations": ours_verifier_bad},
            "ruckig_param_verify_ms_median": 1e3 * statistics.median(compute["jerk_limited"]),
            "toppra_param_verify_ms_median": 1e3 * statistics.median(compute["time_optimal"]),
            "duration_ratio_median": statistics.median(ratios) if ratios else None,
            "duration_ratio_max": max(ratios) if ratios else None,
            "at_vs_evaluate_max_diff": at_mismatch,
        }

    # MPlib, same problems, same machine, same run (its venv is checked before the clock)
    py = mplib_python()
    t0 = time.perf_counter()
    out = run_mplib(spec, py=py)
    mplib_wall = time.perf_counter() - t0
    for scene, results in out["scenes"].items():
        obs = tuple(SCENES[scene])
        world = mp.world(obs)
        verifier = Verifier(lim, mp.dynamics, world, clearance_states=0)
        row = rows[scene]
        e2e = [r["total_s"] for r in results]
        kinds: dict[str, int] = {}
        bad, rebuild, tasks = 0, 0.0, []
        for (a, _, _), r in zip(probs_of[scene], results):
            if not r["success"]:
                continue
            timing = MplibTiming(r, len(names), np.asarray(a, float))
            rebuild = max(rebuild, float(np.max(np.abs(
                timing.evaluate(np.array(r["sample_times"]))[0][:, :3]
                - np.array(r["sample_positions"])))))
            traj = JointTrajectory.sample(timing, mp.dynamics.torques_batch, joint_names=names,
                                          sample_rate=100.0, profile="time_optimal")
            rep = verifier.verify(traj, enforce_jerk=False)
            found = list(rep.violations) + ([] if rep.collision_free else ["collision"])
            bad += bool(found)
            for k in found:
                kinds[k] = kinds.get(k, 0) + 1
            TASKS.append((lambda ts, tm=timing: tm.evaluate(ts)[0], timing.duration, rl,
                          obstacle_dicts(list(obs)), False))
            tasks.append(("mplib", len(TASKS) - 1))
        recheck_of[scene] += tasks
        row["mplib"] = {"success": sum(r["success"] for r in results) / len(results),
                        "start_valid": sum(r["start_valid"] for r in results),
                        **stats(e2e),
                        "plan_ms_median": 1e3 * statistics.median(r["plan_s"] for r in results),
                        "topp_ms_median": 1e3 * statistics.median(
                            [r["param_s"] for r in results if r["success"]] or [0.0]),
                        "verifier_violations": bad, "verifier_kinds": kinds,
                        "rebuild_max_diff_rad": rebuild}
        m, o = row["mplib"]["median_ms"], row["ours"]["median_ms"]
        row["speed_ratio_median"] = m / o if m and o else None

    # the independent re-check of every returned trajectory (not timed; 2 processes)
    with mp_.get_context("fork").Pool(2) as pool:
        reports = pool.map(_recheck_task, range(len(TASKS)))
    for scene, tasks in recheck_of.items():
        rc: dict[str, dict] = {}
        for kind, idx in tasks:
            rep = reports[idx]
            e = rc.setdefault(kind, {"checked": 0, "violating": 0, "kinds": {}})
            e["checked"] += 1
            e["violating"] += bool(rep.violations)
            for k in rep.violations:
                e["kinds"][k] = e["kinds"].get(k, 0) + 1
            if rep.violations:
                print(f"  re-check {scene} {kind}: {rep.violations} worst={rep.worst} "
                      f"first_collision={rep.first_collision}")
        rows[scene]["recheck"] = rc
    rows["mplib_wall_s"] = mplib_wall
    for scene in SCENES:
        r = rows[scene]
        o, m = r["ours"], r["mplib"]
        rc = r["recheck"]
        print(f"{scene:8s} success ours {o['success']:.2f} mplib {m['success']:.2f} | e2e ms "
              f"ours {o['median_ms']:.1f}/{o['p95_ms']:.1f} mplib {m['median_ms']:.1f}/"
              f"{m['p95_ms']:.1f} (median/p95) ratio {r['speed_ratio_median']:.2f}x | "
              f"param+verify ms ruckig {r['ruckig_param_verify_ms_median']:.1f} toppra "
              f"{r['toppra_param_verify_ms_median']:.1f} | duration ratio "
              f"{r['duration_ratio_median']:.3f} | violations verifier ours "
              f"{o['verifier_violations']} mplib {m['verifier_violations']} {m['verifier_kinds']}"
              f" | re-check " + ", ".join(f"{k} {v['violating']}/{v['checked']} {v['kinds']}"
                                           for k, v in rc.items()))
    emit("trajectory", rows)


if __name__ == "__main__":
    main(problems_per_scene(__doc__, 8))
