"""The MuJoCo twin replays every trajectory of the bench scenes; figures, then a JSON line.

Per scene (bench/_lib/scenes.py: the planning benchmark's scenes and seeded problems), each
problem is planned with ``MotionPlanner.solve`` (jerk-limited, and time-optimal with
toppra) and replayed on the twin (src/arduinobot/execution/robots/sim_arduinobot.py: effort-capped
position servos with computed-torque feed-forward, contacts on, the scene's obstacles
in the world) at 100 Hz, faster than real time. Figures per trajectory: tracking error
(max |simulated - commanded| while playing), final error after settling, the torque the
trajectory needs (MuJoCo's inverse dynamics of the commanded motion: the planner's
effort check, re-done independently) and the servos' peak force (feedback on top) over
the effort limit, physics steps at the limit, contacts.

Usage: ``./dev bench simulate [problems per scene]`` (default 8).
"""

from __future__ import annotations

import json
import time

import numpy as np

from arduinobot.contract.errors import PlanningError
from arduinobot.description import load_description
from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
from arduinobot.execution.segments import SampledTrajectory
from arduinobot.execution.simulate import simulate
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
from arduinobot.service.process.disk_cache import DiskCache
from bench._lib.args import problems_per_scene
from bench._lib.report import emit
from bench._lib.scenes import SCENES, obstacle_dicts, problems

ARM = ("joint_1", "joint_2", "joint_3")
PROFILES = ("jerk_limited", "time_optimal")


def main(n: int = 8) -> None:
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    set_ompl_log_level("none")
    d = load_description()
    mp = MotionPlanner(d)
    names = mp.joint_names
    out: dict[str, dict] = {}
    rows = []
    for scene, obs in SCENES.items():
        w = mp.world(tuple(obs))
        probs = problems(w, n, np.random.default_rng(0))
        twin = SimArduinobot(d, obstacles=obstacle_dicts(obs), cache=DiskCache())
        per: dict[str, list] = {p: [] for p in PROFILES}
        failed = 0
        for i, (a, b, _) in enumerate(probs):
            for prof in PROFILES:
                req = MotionRequest(goal=JointGoal(dict(zip(ARM, map(float, b[:3])))),
                                    start=dict(zip(names, map(float, a))), obstacles=tuple(obs),
                                    planning_time=1.0, seed=i, profile=prof)
                try:
                    traj = mp.solve(req).trajectory
                except PlanningError:
                    failed += 1
                    continue
                t0 = time.perf_counter()
                r = simulate(d, SampledTrajectory.from_json({"trajectory": traj.to_dict()}),
                             twin=twin)
                wall = time.perf_counter() - t0
                planned_peak = float(np.max(np.abs(traj.efforts) / mp.limits(1, 1).effort))
                fig = {"scene": scene, "problem": i, "profile": prof,
                       "duration": traj.duration, "wall_s": wall,
                       "tracking_error_mrad": 1000 * max(r.tracking_error),
                       "final_error_mrad": 1000 * max(r.final_error),
                       "force_ratio": r.force_ratio, "need_ratio": r.need_ratio,
                       "planned_effort_ratio": planned_peak,
                       "saturated_steps": r.saturated_steps, "steps": r.steps,
                       "contacts": ["/".join(p) for p in r.contacts]}
                per[prof].append(fig)
                rows.append(fig)
                print(f"{scene:8s} #{i} {prof:12s} {traj.duration:6.3f} s  track "
                      f"{fig['tracking_error_mrad']:7.3f} mrad  final "
                      f"{fig['final_error_mrad']:6.3f} mrad  needs {100 * r.need_ratio:5.1f}% "
                      f"(planner {100 * planned_peak:5.1f}%)  servo peak "
                      f"{100 * r.force_ratio:5.1f}%  sat {r.saturated_steps:4d}/"
                      f"{r.steps}  contacts {fig['contacts'] or '-'}  ({wall:.2f} s)")
        out[scene] = {"failed_plans": failed, **{
            prof: {"trajectories": len(v),
                   "tracking_error_mrad_max": max((f["tracking_error_mrad"] for f in v),
                                                  default=None),
                   "tracking_error_mrad_median": float(np.median(
                       [f["tracking_error_mrad"] for f in v])) if v else None,
                   "need_ratio_max": max((f["need_ratio"] for f in v), default=None),
                   "needing_over_effort": sum(f["need_ratio"] > 1 + 1e-3 for f in v),
                   "with_saturation": sum(f["saturated_steps"] > 0 for f in v),
                   "saturated_steps_max": max((f["saturated_steps"] for f in v),
                                              default=None),
                   "with_contacts": sum(bool(f["contacts"]) for f in v)}
            for prof, v in per.items()}}
        print(scene, json.dumps(out[scene]))
    total = {"trajectories": len(rows),
             "needing_over_effort": sum(f["need_ratio"] > 1 + 1e-3 for f in rows),
             "need_ratio_max": max(f["need_ratio"] for f in rows),
             "with_saturation": sum(f["saturated_steps"] > 0 for f in rows),
             "with_contacts": sum(bool(f["contacts"]) for f in rows),
             "tracking_error_mrad_max": max(f["tracking_error_mrad"] for f in rows),
             "force_ratio_max": max(f["force_ratio"] for f in rows),
             "sim_speed_x_realtime": sum(f["duration"] for f in rows)
             / sum(f["wall_s"] for f in rows)}
    emit("simulate", {"scenes": out, "total": total})


if __name__ == "__main__":
    main(problems_per_scene(__doc__, 8))
