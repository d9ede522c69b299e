"""Point-cloud benchmark (issue 40): a 300k-point cloud made ready to plan against, and
plans among its ~50k cells against the same scene as two boxes.

In process, on the shipped arm: a table (2.4 m square, under the arm) and a pillar in
its way, measured with 3 mm of noise and 1% NaN holes at 1 cm cells.

- apply: decode (base64 xyz32 -> points), keep (pose, voxelise, self-filter at the
  state), world (the cells joined into boxes and their tree, the boundary's tiles, the
  hull; a world with them): median of R clouds, each new content (no geometry cache
  hit). The tiles' FCL BVHs are built by the first queries near them: the first plan
  and proof in each new cloud's world is timed apart (``first_plan_ms``), with the
  tiles it built.
- plans: the same seeded requests (a base swing around the pillar) in the cloud's world
  and in the world of the table and pillar as two boxes, each run once untimed first
  (the tiles they come near built): median plan and proof [ms].
- MPlib 0.2.1 in the same run (its own venv, bench/_lib/mplib_cloud.py): its
  ``update_point_cloud`` (an FCL OcTree) on the same finite points at the same
  resolution, and its RRTConnect plans (no timing, no proof) for the same start and
  goal. ``--no-mplib`` skips it.

    ./dev bench cloud [--repeats 3] [--plans 10] [--no-mplib]
    ./dev bench cloud --table 1.2 --points 150000   (a smaller table: about 50k cells)
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

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
from bench._lib.mplib_venv import mplib_python
from bench._lib.peer_models import shipped_model
from bench._lib.peer_mplib import move_group_link, mplib_start
from bench._lib.report import emit

MPLIB_CLOUD = Path(__file__).with_name("_lib") / "mplib_cloud.py"

START = np.array([1.2, -0.6, -0.6, 0.0])
GOAL = JointGoal({"joint_1": -1.2, "joint_2": -0.6, "joint_3": -0.6})


def table_box(side: float) -> Obstacle:
    """The table as a box: ``side`` [m] square, its top at z = -0.15."""
    return Obstacle("table", "box", size=(side, side, 0.02), xyz=(0.0, 0.0, -0.16))


PILLAR = Obstacle("pillar", "box", size=(0.15, 0.15, 3.0), xyz=(0.0, 0.9, 0.6))


def measured(rng: np.random.Generator, n: int = 300_000, side: float = 2.4) -> np.ndarray:
    """The table's top (``side`` [m] square) and the pillar's sides as a depth camera
    returns them, shape (n, 3)."""
    m = n // 2
    h = side / 2
    table = np.column_stack([rng.uniform(-h, h, m), rng.uniform(-h, h, m),
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
    ap.add_argument("--no-mplib", action="store_true", help="skip MPlib's column")
    ap.add_argument("--table", type=float, default=2.4,
                    help="the table's side [m] (default 2.4: ~113k cells at 1 cm; 1.2: ~50k)")
    ap.add_argument("--points", type=int, default=300_000,
                    help="points per cloud, half on the table (default 300,000)")
    args = ap.parse_args()
    d = load_description()
    base = CollisionWorld(d)
    rng = np.random.default_rng(0)
    decode, keep, build, first, cells, built = [], [], [], [], 0, []
    world = base
    pts = measured(rng, args.points, args.table)
    for _ in range(args.repeats + 1):  # the first warms numba and the surface samples
        pts = measured(rng, args.points, args.table)
        wire = {"id": "camera", "shape": "points", "points": encode_points(pts),
                "resolution": 0.01}
        t0 = time.perf_counter()
        spec = CloudSpec.from_mapping(wire, link_names=base.kin.link_names)
        t1 = time.perf_counter()
        kept = keep_cloud(base, spec, START)
        t2 = time.perf_counter()
        world = base.with_scene(clouds=kept.bodies)
        t3 = time.perf_counter()
        r = PathPlanner(world, d).solve(PathRequest(start=START, goal=GOAL, seed=0))
        Certifier(world).path(r.path)
        t4 = time.perf_counter()
        decode.append(t1 - t0)
        keep.append(t2 - t1)
        build.append(t3 - t2)
        first.append(t4 - t3)
        cells = kept.counts.cells
        tiles = next(iter(world._tiled.values()))
        built.append((tiles.built, len(tiles)))
    decode, keep, build, first = decode[1:], keep[1:], build[1:], first[1:]
    ms = 1e3
    print(f"apply of {args.points:,} points -> {cells} cells: decode {statistics.median(decode) * ms:.0f}"
          f" ms, keep {statistics.median(keep) * ms:.0f} ms, world "
          f"{statistics.median(build) * ms:.0f} ms (median of {args.repeats}); the first "
          f"plan and proof {statistics.median(first) * ms:.0f} ms, building "
          f"{built[-1][0]} of {built[-1][1]} tiles")
    boxes = base.with_scene([table_box(args.table), PILLAR])
    figures = {"points": args.points, "table_m": args.table, "cells": cells,
               "decode_ms": statistics.median(decode) * ms,
               "keep_ms": statistics.median(keep) * ms,
               "world_ms": statistics.median(build) * ms,
               "first_plan_ms": statistics.median(first) * ms,
               "tiles": built[-1][1], "tiles_built": built[-1][0]}
    figures["apply_ms"] = figures["decode_ms"] + figures["keep_ms"] + figures["world_ms"]
    runs = {name: (PathPlanner(w, d), Certifier(w)) for name, w in
            (("boxes", boxes), ("cloud", world))}
    for pp, cert in runs.values():
        for seed in range(args.plans + 1):  # warm: the tiles these plans come near built
            cert.path(pp.solve(PathRequest(start=START, goal=GOAL, seed=seed)).path)
    times: dict[str, tuple[list[float], list[float]]] = {n: ([], []) for n in runs}
    for seed in range(1, args.plans + 1):
        # interleaved, seed by seed: the machine's other load falls on both alike
        for name, (pp, cert) in runs.items():
            t0 = time.perf_counter()
            r = pp.solve(PathRequest(start=START, goal=GOAL, seed=seed))
            t1 = time.perf_counter()
            c = cert.path(r.path)
            t2 = time.perf_counter()
            if not c.free:
                raise SystemExit(f"{name}: seed {seed}'s path was not certified: {c}")
            times[name][0].append(t1 - t0)
            times[name][1].append(t2 - t1)
    for name, (plan, proof) in times.items():
        figures[f"{name}_plan_ms"] = statistics.median(plan) * ms
        figures[f"{name}_proof_ms"] = statistics.median(proof) * ms
        figures[f"{name}_plan_p95_ms"] = float(np.percentile(plan, 95)) * ms
        figures[f"{name}_proof_p95_ms"] = float(np.percentile(proof, 95)) * ms
        print(f"{name}: plan {figures[f'{name}_plan_ms']:.1f} ms (p95 "
              f"{figures[f'{name}_plan_p95_ms']:.1f}), proof "
              f"{figures[f'{name}_proof_ms']:.1f} ms (p95 "
              f"{figures[f'{name}_proof_p95_ms']:.1f}; median of {args.plans})")
    figures["plan_ratio"] = figures["cloud_plan_ms"] / figures["boxes_plan_ms"]
    if not args.no_mplib:
        figures.update(run_mplib_cloud(pts, args))
    emit("cloud", figures)


def run_mplib_cloud(pts: np.ndarray, args: argparse.Namespace) -> dict[str, object]:
    """MPlib's ``update_point_cloud`` and plans on ``pts`` (the last cloud measured)."""
    py = mplib_python()
    with tempfile.TemporaryDirectory() as tmp:
        model = shipped_model(Path(tmp))
        names = tuple(model.description.robot.joints)
        finite = pts[np.isfinite(pts).all(axis=1)]
        np.save(Path(tmp) / "points.npy", finite)
        joints = ("joint_1", "joint_2", "joint_3", "joint_4")
        spec = {"urdf": str(model.urdf), "srdf": str(model.srdf),
                "move_group": move_group_link(model, "arm"),
                "points": str(Path(tmp) / "points.npy"), "resolution": 0.01,
                "repeats": args.repeats, "plans": args.plans, "planning_time": 1.0,
                "start": mplib_start(model, names, np.array(
                    [dict(zip(joints, START)).get(n, 0.0) for n in names])),
                "goal": {**dict(zip(joints, map(float, START))), **GOAL.values},
                "output": str(Path(tmp) / "out.json")}
        done = subprocess.run([str(py), str(MPLIB_CLOUD)], input=json.dumps(spec),
                              text=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        if done.returncode:
            raise RuntimeError(f"mplib_cloud failed ({done.returncode}):\n"
                               f"{done.stderr[-3000:]}")
        out = json.loads((Path(tmp) / "out.json").read_text())
    ok = [t for t, st in zip(out["plan_s"], out["status"]) if st == "Exact solution"]
    fig = {"mplib_points": len(finite),
           "mplib_update_ms": statistics.median(out["update_s"]) * 1e3,
           "mplib_start_valid": out["start_valid"],
           "mplib_solved": f"{len(ok)}/{len(out['status'])}",
           "mplib_statuses": sorted(set(out["status"])),
           "mplib_plan_ms": statistics.median(ok) * 1e3 if ok else None}
    plan = f"{fig['mplib_plan_ms']:.1f} ms" if ok else "none solved"
    print(f"MPlib 0.2.1: update_point_cloud of {len(finite)} points "
          f"{fig['mplib_update_ms']:.0f} ms (median of {args.repeats}); start "
          f"{'free' if out['start_valid'] else 'IN COLLISION'}; plans {fig['mplib_solved']} "
          f"solved ({', '.join(fig['mplib_statuses'])}), {plan} median (RRTConnect "
          "only: no timing, no proof)")
    return fig


if __name__ == "__main__":
    main()
