"""Kept-scene benchmark: concurrent writers with if_revision through two instances, and
plans against a kept scene against the same obstacles sent in every request.

Starts a Zenoh router (in this process) and two `arduinobot serve` instances on free
loopback ports, each with its own scene file in a temporary folder. Prints figures, then
one line of JSON.

- writers: W writers (half through each instance) x N applies, each replacing its own
  object with ``if_revision``; every acknowledged apply must be one revision and the
  scene must end with each writer's last acknowledged object (``lost`` counts those
  missing), every refusal SCENE_CONFLICT (``other_errors`` counts the rest).
- fuzz: hostile applies (mutations, junk meshes, raw bytes) through both instances:
  every reply coded, 0 INTERNAL, 0 missing, the instances' scenes equal after.
- plans: the same R plan requests (seeded) with 20 objects (17 primitives and 3 stand-in
  boxes) sent in each request, with the same 20 kept in the scene, with 17
  primitives plus 3 meshes of ~10k triangles kept, and at the next revision (one more
  sphere; the meshes' geometry is cached by content, not rebuilt): median and p95 of the
  latency a client sees [ms], and the first plan of each (its world built).

    ./dev bench scene [--writers 4] [--applies 250] [--fuzz 2000] [--plans 30]
"""

from __future__ import annotations

import argparse
import base64
import collections
import json
import math
import random
import statistics
import tempfile
import threading
import time
from pathlib import Path

import trimesh
import zenoh

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.contract.zconfig import zenoh_config
from bench._lib.report import emit
from tests.helpers.scene_fuzz import b64, carry_seeds, mutate
from tests.helpers.serve import Server, free_port, launch_serves

# a base swing from reach_right to reach_left (bench/service.py's), several seeds
# (reach_left as joint values: the course workspace's SRDF names only home, open, closed)
REQUEST = {"start": {"joint_1": -1.2, "joint_2": 0.5, "joint_3": 0.9},
           "goal": {"joints": {"joint_1": 1.2, "joint_2": 0.5, "joint_3": 0.9}},
           "velocity_scaling": 0.2,
           "acceleration_scaling": 0.13, "sample_rate": 100}


def serve(endpoint: str, scene_files: list[Path], workers: int, model: list[str]
          ) -> list[Server]:
    """One instance per scene file, each connected to the router at ``endpoint``."""
    return launch_serves([["--connect", endpoint, "--listen", f"tcp/127.0.0.1:{free_port()}",
                           "--workers", str(workers), "--scene-file", str(f), *model]
                          for f in scene_files])


def stop(server: Server, log: Path) -> None:
    server.stop()
    log.write_text("\n".join(server.stderr_lines) + "\n")


def ms(values: list[float]) -> dict[str, float]:
    s = sorted(values)
    return {"median": round(1e3 * statistics.median(s), 2),
            "p95": round(1e3 * s[min(len(s) - 1, math.ceil(0.95 * len(s)) - 1)], 2)}


def writers(endpoint: str, instances: list[str], n_writers: int, applies: int) -> dict:
    acked: dict[int, list[str]] = {k: [] for k in range(n_writers)}
    conflicts = [0] * n_writers
    other: list[str] = []
    latencies: list[float] = []
    with PlannerClient(endpoint, timeout=60) as c:
        start = c.request("scene/apply", {"clear": True})["revision"]

    def run(k: int) -> None:
        inst = instances[k % len(instances)]
        with PlannerClient(endpoint, timeout=60) as c:
            i = 0
            while len(acked[k]) < applies:
                rev = c.request("scene", instance=inst)["revision"]
                change = {"add": [{"id": f"w{k}-{i}", "shape": "sphere", "radius": 0.01,
                                   "xyz": [3, k, 3]}], "if_revision": rev}
                if acked[k]:
                    change["remove"] = [acked[k][-1]]
                t0 = time.perf_counter()
                try:
                    c.request("scene/apply", change, instance=inst)
                except errors.SceneConflict:
                    conflicts[k] += 1
                    i += 1
                    continue
                except errors.ServiceError as e:
                    other.append(f"{e.code}: {e.message}")
                    return
                latencies.append(time.perf_counter() - t0)
                acked[k].append(f"w{k}-{i}")
                i += 1

    t0 = time.perf_counter()
    threads = [threading.Thread(target=run, args=(k,)) for k in range(n_writers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - t0
    total = sum(len(v) for v in acked.values())
    lost = 0
    with PlannerClient(endpoint, timeout=60) as c:
        for inst in instances:
            scene = c.request("scene", instance=inst)
            want = {v[-1] for v in acked.values() if v}
            have = {o["id"] for o in scene["objects"]}
            lost += len(want - have) + abs(scene["revision"] - (start + total))
    return {"writers": n_writers, "applies_each": applies, "acknowledged": total,
            "conflicts": sum(conflicts), "other_errors": len(other), "lost": lost,
            "apply_ms": ms(latencies), "wall_s": round(wall, 1),
            "errors": other[:3]}


def fuzz(endpoint: str, instances: list[str], cases: int, seed: int = 28) -> dict:
    """Hostile applies (mutated valid ones, junk meshes, raw bytes) through both
    instances; every 10th a valid one that must succeed. Counts replies by code."""
    r = random.Random(seed)
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    seeds = [
        {"add": [{"id": "m", "shape": "mesh", "xyz": [2, 2, 2], "scale": [1, 2, 3],
                  "mesh": {"format": "stl", "data": b64(box.export(file_type="stl"))}}]},
        {"add": [{"id": "o", "shape": "mesh", "xyz": [2, -2, 2], "mesh": {
            "format": "obj", "data": b64(box.export(file_type="obj").encode())}}],
         "remove": ["keep"], "if_revision": 1},
        {"add": [{"id": "c", "shape": "cylinder", "radius": 0.1, "length": 1,
                  "frame": "world", "xyz": [3, 0, 0]}], "attach": [], "detach": []},
        *carry_seeds()]  # attach, detach and state (issue 28)
    counts: collections.Counter[str] = collections.Counter()
    valid_failed = 0
    busy: list[str] = []
    with PlannerClient(endpoint, timeout=60) as c:
        for i in range(cases):
            inst = instances[i % len(instances)]
            if i % 10 == 0:
                try:
                    c.request("scene/apply", {"clear": True, "add": [
                        {"id": "keep", "shape": "sphere", "radius": 0.05, "xyz": [3, 3, 3]}]},
                              instance=inst)
                except errors.ServiceError:
                    valid_failed += 1
                continue
            if r.random() < 0.1:
                payload: bytes = bytes(r.getrandbits(8) for _ in range(r.randrange(200)))
            else:
                change = seeds[r.randrange(len(seeds))]
                for _ in range(r.randrange(1, 4)):
                    change = mutate(r, change)
                payload = json.dumps(change).encode()
            try:
                c.request("scene/apply", payload, instance=inst)
                counts["ok"] += 1
            except errors.ServiceUnavailable:
                counts["missing"] += 1
            except errors.ServiceError as e:
                counts[str(e.code)] += 1
                if str(e.code) == "BUSY":  # a retry, not a refusal: say why it came
                    busy.append(e.message)
        scenes = [c.request("scene", instance=inst) for inst in instances]
    return {"cases": cases, "replies": dict(counts), "internal": counts.get("INTERNAL", 0),
            "missing": counts.get("missing", 0), "valid_failed": valid_failed,
            "busy": busy,
            "instances_agree": all(sc == scenes[0] for sc in scenes)}


def objects(*, meshes: bool) -> list[dict]:
    """17 primitives and 3 more objects (meshes of ~10k triangles, or boxes) in a ring
    around the arm, out of its way."""
    out: list[dict] = []
    for i in range(17):
        a = 2 * math.pi * i / 20
        xyz = [round(2.0 * math.cos(a), 4), round(2.0 * math.sin(a), 4), 0.5]
        shape = ("box", "sphere", "cylinder")[i % 3]
        o: dict = {"id": f"p{i}", "shape": shape, "xyz": xyz}
        if shape == "box":
            o["size"] = [0.3, 0.2, 0.4]
        elif shape == "sphere":
            o["radius"] = 0.15
        else:
            o["radius"], o["length"] = 0.1, 0.5
        out.append(o)
    for j in range(3):
        a = 2 * math.pi * (17 + j) / 20
        xyz = [round(2.0 * math.cos(a), 4), round(2.0 * math.sin(a), 4), 0.5]
        if meshes:
            torus = trimesh.creation.torus(0.2, 0.05, major_sections=100, minor_sections=50)
            data = base64.b64encode(torus.export(file_type="stl")).decode()
            out.append({"id": f"m{j}", "shape": "mesh", "xyz": xyz,
                        "mesh": {"format": "stl", "data": data}})
        else:
            out.append({"id": f"m{j}", "shape": "box", "size": [0.5, 0.5, 0.1], "xyz": xyz})
    return out


def plans(endpoint: str, instance: str, n: int) -> dict:
    prims = objects(meshes=False)
    runs: dict = {}
    first: list[float] = []  # the first plan of each: its world is built [ms]
    with PlannerClient(endpoint, timeout=120) as c:
        def timed(req: dict) -> list[float]:
            t0 = time.perf_counter()
            c.plan({**REQUEST, **req, "seed": 10_000}, instance=instance)  # builds the world
            first.append(round(1e3 * (time.perf_counter() - t0), 1))
            out = []
            for seed in range(n):
                t0 = time.perf_counter()
                c.plan({**REQUEST, **req, "seed": seed}, instance=instance)
                out.append(time.perf_counter() - t0)
            return out
        c.request("scene/apply", {"clear": True})
        runs["per_request_20_primitives"] = ms(timed({"obstacles": prims}))
        c.request("scene/apply", {"clear": True, "add": prims})
        runs["kept_20_primitives"] = ms(timed({}))
        c.request("scene/apply", {"clear": True, "add": objects(meshes=True)})
        runs["kept_17_primitives_3_meshes_10k"] = ms(timed({}))
        # the next revision keeps the meshes: their geometry is not built again
        c.request("scene/apply", {"add": [{"id": "late", "shape": "sphere", "radius": 0.1,
                                           "xyz": [-2.0, -2.0, 0.5]}]})
        runs["kept_meshes_next_revision"] = ms(timed({}))
        c.request("scene/apply", {"clear": True})
        runs["no_obstacles"] = ms(timed({}))
    for name, t in zip(list(runs), first):
        runs[name]["first_ms"] = t
    return runs


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--writers", type=int, default=4)
    p.add_argument("--applies", type=int, default=250)
    p.add_argument("--plans", type=int, default=30)
    p.add_argument("--fuzz", type=int, default=2000, metavar="CASES",
                   help="hostile applies through the instances (default 2000)")
    p.add_argument("--course", action="store_true",
                   help="serve the course workspace (CAD meshes of 20k-54k triangles, "
                   "tests/helpers/course_workspace.py) instead of the shipped arm")
    p.add_argument("--keep", metavar="DIR", help="keep the scene files and the instances' "
                   "logs (<x>.log) in DIR")
    ns = p.parse_args()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(zenoh_config(mode="router", listen=[endpoint]))
    procs = []
    with tempfile.TemporaryDirectory() as tmp:
        d = ns.keep or tmp
        try:
            model: list[str] = []
            if ns.course:
                from tests.helpers.course_workspace import make_course_workspace
                ws = make_course_workspace(Path(d) / "ws")
                model = [str(ws.xacro), "--package-dir", str(ws.src), "--moveit-config",
                         str(ws.moveit_pkg), "--cache-dir", str(Path(d) / "cache")]
            files = [Path(d) / f"{x}.json" for x in "ab"]
            procs = list(zip(serve(endpoint, files, 1, model), files))
            with PlannerClient(endpoint, timeout=60) as c:
                deadline = time.monotonic() + 30
                while len(live := c.instances(refresh=True)) < 2:
                    if time.monotonic() > deadline:
                        raise SystemExit("the instances did not come up")
                    time.sleep(0.1)
            w = writers(endpoint, list(live), ns.writers, ns.applies)
            print(f"writers: {w['writers']} x {w['applies_each']} applies through 2 "
                  f"instances: {w['acknowledged']} acknowledged, {w['conflicts']} "
                  f"SCENE_CONFLICT, {w['other_errors']} other errors, {w['lost']} lost; "
                  f"apply median {w['apply_ms']['median']} ms, p95 {w['apply_ms']['p95']} "
                  f"ms; {w['wall_s']} s")
            fz = fuzz(endpoint, list(live), ns.fuzz)
            print(f"fuzz: {fz['cases']} hostile applies: {fz['replies']}; INTERNAL "
                  f"{fz['internal']}, missing {fz['missing']}, valid failed "
                  f"{fz['valid_failed']}, instances agree: {fz['instances_agree']}")
            for m in fz["busy"]:
                print(f"  BUSY (retry): {m}")
            pl = plans(endpoint, live[0], ns.plans)
            for name, fig in pl.items():
                print(f"plan {name}: median {fig['median']} ms, p95 {fig['p95']} ms "
                      f"(the first, building its world: {fig['first_ms']} ms)")
        finally:
            for server, f in procs:
                stop(server, f.with_suffix(".log"))
            router.close()
    emit("scene", {"robot": "course workspace" if ns.course else "shipped arm",
                   "writers": w, "fuzz": fz, "plans": pl})


if __name__ == "__main__":
    main()
