"""Reaction benchmark: time from a scene apply's arrival to the stop command of a moving arm.

Starts `arduinobot serve` (the MuJoCo twin, one worker by default) and runs N seeded
variants: from home, a slow joint motion towards a goal drawn from a seeded generator;
when the stream's progress passes ``--at``, a sphere is applied to the kept scene where
the planned motion has its claw at ``--on-path`` of its time. Each run must stop before
the obstacle (``on_change: stop``): the ``stopped`` event's ``before``. Figures: the
``stopped`` event's ``stop_ms`` (the apply's arrival at the service to the first stop
setpoint sent, wall clock [ms]) and its parts from the ``changed`` event: ``heard_ms``
(the apply applied, kept on disk and published), ``decided_ms`` (the rest sampled,
certified by a worker, the halt set) and ``recheck_ms`` (the worker's certification
alone), median and p95; runs that did not stop before the obstacle (``not_before``: the
arm had passed the last certified state when the stop came, the obstacle appearing
closer ahead than the reaction's distance).

    ./dev bench react [--runs 20] [--seed 1] [--workers 1] [--at 0.15] [--on-path 0.5]
"""

from __future__ import annotations

import argparse
import math
import statistics
import threading

import numpy as np

from arduinobot.client.client import PlannerClient
from arduinobot.description import load_description
from bench._lib.report import emit
from tests.helpers.fk import link_pose
from tests.helpers.serve import start_server


def stats(values: list[float]) -> dict[str, float]:
    s = sorted(values)
    if not s:
        return {"median": float("nan"), "p95": float("nan")}
    return {"median": round(statistics.median(s), 1),
            "p95": round(s[min(len(s) - 1, math.ceil(0.95 * len(s)) - 1)], 1)}


def variant(rng: np.random.Generator) -> dict:
    """One seeded motion: a slow joint goal (the planner's seed drawn too)."""
    goal = {"joint_1": float(rng.uniform(-1.2, -0.6)) * float(rng.choice([-1, 1])),
            "joint_2": float(rng.uniform(0.1, 0.4)), "joint_3": float(rng.uniform(0.2, 0.6))}
    return {"goal": {"joints": goal}, "velocity_scaling": 0.03,
            "acceleration_scaling": 0.03, "seed": int(rng.integers(1 << 30))}


def one_run(c: PlannerClient, desc, rng: np.random.Generator, *, at: float,
            on_path: float) -> dict:
    c.apply(clear=True)
    c.execute(plan={"goal": {"named": "home"}}, move_to_start=True)
    req = variant(rng)
    st = c.robot_state()
    start = {n: float(v) for n, v in zip(st["name"], st["position"])
             if n in desc.robot.actuated_joints}
    plan = c.plan({**req, "start": start})
    q = plan.positions[int(on_path * (len(plan.times) - 1))]
    xyz = link_pose(desc.robot, "claw_support", list(plan.joint_names), q)[:3, 3]
    ob = {"id": "intruder", "shape": "sphere", "radius": 0.08, "xyz": [float(v) for v in xyz]}
    events: list[dict] = []
    applied = threading.Event()

    def on_event(ev) -> None:
        events.append(dict(ev.raw))
        if ev.event == "progress" and ev.raw.get("progress", 0) >= at and not applied.is_set():
            applied.set()
            threading.Thread(target=c.apply, kwargs={"add": [ob]}, daemon=True).start()
    done = c.execute(plan=req, on_change="stop", on_event=on_event)
    changed = next((e for e in events if e["event"] == "changed"), {})
    stopped = next((e for e in events if e["event"] == "stopped"), {})
    return {"outcome": done.report["outcome"], "before": bool(stopped.get("before")),
            "stop_ms": stopped.get("stop_ms"), "recheck_ms": changed.get("recheck_ms"),
            "heard_ms": changed.get("heard_ms"), "decided_ms": changed.get("decided_ms"),
            "certified": changed.get("certified"),
            "stopped_at": stopped.get("trajectory_time"), "rest_at": stopped.get("rest_at"),
            "certified_until": stopped.get("certified_until"),
            "stop_kind": stopped.get("stop_kind"), "refused": changed.get("refused")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--first", type=int, default=0, help="skip this many variants")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--at", type=float, default=0.15,
                    help="progress at which the obstacle is applied")
    ap.add_argument("--on-path", type=float, default=0.5,
                    help="where on the planned motion (fraction of its time) it is put")
    a = ap.parse_args()
    desc = load_description(env={})
    rng = np.random.default_rng(a.seed)
    srv = start_server(["--workers", str(a.workers)], timeout=300)
    runs = []
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            for i in range(a.first + a.runs):
                if i < a.first:  # the same draws as a whole run makes
                    variant(rng)
                    continue
                r = one_run(c, desc, rng, at=a.at, on_path=a.on_path)
                runs.append(r)
                print(f"run {i}: {r['outcome']}, stop {r['stop_ms']:.0f} ms, recheck "
                      f"{r['recheck_ms']:.0f} ms; stop at {r['stopped_at']} s "
                      f"({r['stop_kind']}), rest at {r['rest_at']} s, certified until "
                      f"{r['certified_until']} s, refused {r['refused']}", flush=True)
    finally:
        srv.stop()
    stop = [r["stop_ms"] for r in runs if r["stop_ms"] is not None]
    rech = [r["recheck_ms"] for r in runs if r["recheck_ms"] is not None]
    heard = [r["heard_ms"] for r in runs if r["heard_ms"] is not None]
    decided = [r["decided_ms"] for r in runs if r["decided_ms"] is not None]
    figures = {"runs": len(runs), "stopped": sum(r["outcome"] == "stopped" for r in runs),
               "not_before": sum(not r["before"] for r in runs),
               "stop_ms": stats(stop), "heard_ms": stats(heard),
               "decided_ms": stats(decided), "recheck_ms": stats(rech)}
    print(f"apply -> stop command: median {figures['stop_ms']['median']} ms, p95 "
          f"{figures['stop_ms']['p95']} ms over {len(stop)} stops (heard after "
          f"{figures['heard_ms']['median']} ms, decided after "
          f"{figures['decided_ms']['median']} ms, of which the worker's recheck "
          f"{figures['recheck_ms']['median']} ms: medians); stopped "
          f"{figures['stopped']}/{len(runs)}, not before the obstacle "
          f"{figures['not_before']}")
    emit("react", figures)


if __name__ == "__main__":
    main()
