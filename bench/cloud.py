"""Point-cloud benchmark (issue 40): a 300k-point cloud made ready to plan against, and
plans among its ~50k cells against the same scene as two boxes.

In process, on the shipped arm: a table (2.4 m square, under the arm) and a pillar in
its way, measured with 3 mm of noise and 1% NaN holes at 1 cm cells.

- apply: decode (base64 xyz32 -> points), keep (pose, voxelise, self-filter at the
  state), world (the cells' tree, faces and hull; a world with them): median of R
  clouds, each new content (no geometry cache hit).
- plans: the same seeded requests (a base swing around the pillar) in the cloud's world
  and in the world of the table and pillar as two boxes: median plan and proof [ms].

MPlib's ``update_point_cloud`` on the same points is not in this run yet (see
bench/_lib/peer_mplib.py for how MPlib runs in its own venv).

    ./dev bench cloud [--repeats 3] [--plans 10]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from arduinobot.description import load_description
from arduinobot.planner.collision.cloud_keep import keep_cloud
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.pathfinding.paths import PathPlanner, PathRequest
from arduinobot.scene.cloud import encode_points
from arduinobot.scene.cloud_spec import CloudSpec
from arduinobot.scene.obstacles import Obstacle
from bench._lib.report import emit

START = np.array([1.2, -0.6, -0.6, 0.0])
GOAL = JointGoal({"joint_1": -1.2, "joint_2": -0.6, "joint_3": -0.6})
TABLE = Obstacle("table", "box", size=(2.4, 2.4, 0.02), xyz=(0.0, 0.0, -0.16))
PILLAR = Obstacle("pillar", "box", size=(0.15, 0.15, 3.0), xyz=(0.0, 0.9, 0.6))


def measured(rng: np.random.Generator, n: int = 300_000) -> np.ndarray:
    """The table's top and the pillar's sides as a depth camera returns them."""
    m = n // 2
    table = np.column_stack([rng.uniform(-1.2, 1.2, m), rng.uniform(-1.2, 1.2, m),
                             np.full(m, -0.15)])
    size = np.array([0.15, 0.15, 3.0])
    p = rng.uniform(-0.5, 0.5, (n - m, 3)) * size
    ax = rng.integers(0, 2, n - m)
    p[np.arange(n - m), ax] = np.sign(rng.uniform(-1, 1, n - m)) * size[ax] / 2
    pts = np.vstack([table, p + [0.0, 0.9, 0.6]]) + rng.normal(0, 0.003, (n, 3))
    pts[rng.choice(n, n // 100, replace=False)] = np.nan
    return pts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--plans", type=int, default=10)
    args = ap.parse_args()
    d = load_description()
    base = CollisionWorld(d)
    rng = np.random.default_rng(0)
    decode, keep, build, cells = [], [], [], 0
    world = base
    for _ in range(args.repeats + 1):  # the first warms numba and the surface samples
        wire = {"id": "camera", "shape": "points", "points": encode_points(measured(rng)),
                "resolution": 0.01}
        t0 = time.perf_counter()
        spec = CloudSpec.from_mapping(wire, link_names=base.kin.link_names)
        t1 = time.perf_counter()
        kept = keep_cloud(base, spec, START)
        t2 = time.perf_counter()
        world = base.with_scene(clouds=kept.bodies)
        t3 = time.perf_counter()
        decode.append(t1 - t0)
        keep.append(t2 - t1)
        build.append(t3 - t2)
        cells = kept.counts.cells
    decode, keep, build = decode[1:], keep[1:], build[1:]
    ms = 1e3
    print(f"apply of 300,000 points -> {cells} cells: decode {statistics.median(decode) * ms:.0f}"
          f" ms, keep {statistics.median(keep) * ms:.0f} ms, world "
          f"{statistics.median(build) * ms:.0f} ms (median of {args.repeats})")
    boxes = base.with_scene([TABLE, PILLAR])
    figures = {"points": 300_000, "cells": cells,
               "decode_ms": statistics.median(decode) * ms,
               "keep_ms": statistics.median(keep) * ms,
               "world_ms": statistics.median(build) * ms}
    for name, w in (("boxes", boxes), ("cloud", world)):
        pp, cert = PathPlanner(w, d), Certifier(w)
        pp.solve(PathRequest(start=START, goal=GOAL, seed=0))  # warm
        plan, proof = [], []
        for seed in range(1, args.plans + 1):
            t0 = time.perf_counter()
            r = pp.solve(PathRequest(start=START, goal=GOAL, seed=seed))
            t1 = time.perf_counter()
            c = cert.path(r.path)
            t2 = time.perf_counter()
            if not c.free:
                raise SystemExit(f"{name}: seed {seed}'s path was not certified: {c}")
            plan.append(t1 - t0)
            proof.append(t2 - t1)
        figures[f"{name}_plan_ms"] = statistics.median(plan) * ms
        figures[f"{name}_proof_ms"] = statistics.median(proof) * ms
        print(f"{name}: plan {figures[f'{name}_plan_ms']:.1f} ms, proof "
              f"{figures[f'{name}_proof_ms']:.1f} ms (median of {args.plans})")
    figures["plan_ratio"] = figures["cloud_plan_ms"] / figures["boxes_plan_ms"]
    emit("cloud", figures)


if __name__ == "__main__":
    main()
