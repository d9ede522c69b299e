"""Mesh churn: the serving process's resident set while the kept scene's meshes change.

One real ``arduinobot serve`` (1 worker, 127.0.0.1 on a free port); each round clears the
kept scene and adds ``--meshes`` new meshes near the mesh cap (seeded, different every
round, so nothing is found by content): binary STL of 41,000 triangles (2.05 MB) and OBJ
text of 199,000 triangles (1.6 MB; the parse's heaviest case per byte), alternately.
Then the scene filled near ``MAX_SCENE_MESH_BYTES`` (one apply of 16 such STL) and three
applies of one more (junk bytes: refused by the cap, naming the field, before any parse). Figures: the serving process's RSS [MiB] at start, after each
round (max and last) and after the refusals, the trims of ``malloc_trim`` given time
(``--settle`` s, the serving process trims every 10 s), and the apply times.

Usage: ./dev bench mesh_churn [--rounds 40] [--meshes 4] [--settle 12]
"""

from __future__ import annotations

import argparse
import base64
import time

import numpy as np
import trimesh

from arduinobot.client.client import PlannerClient
from arduinobot.client.errors import ServiceError
from arduinobot.contract.caps import MAX_SCENE_MESH_BYTES
from arduinobot.service.process.pool import rss_bytes
from bench._lib.report import emit
from tests.helpers.serve import start_server

MIB = 2**20


def _stl(rng: np.random.Generator) -> dict:
    s = trimesh.creation.icosphere(subdivisions=6)
    m = trimesh.Trimesh(0.1 * s.vertices + rng.normal(0, 1e-4, s.vertices.shape),
                        s.faces[:41_000], process=False)
    return {"format": "stl", "data": base64.b64encode(m.export(file_type="stl")).decode()}


def _obj(rng: np.random.Generator) -> dict:
    cube = trimesh.creation.box(extents=rng.uniform(0.05, 0.1, 3))
    v = "".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in cube.vertices)
    faces = "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in cube.faces)
    return {"format": "obj", "data": base64.b64encode(
        (v + faces * (199_000 // 12)).encode()).decode()}


def _meshes(rng: np.random.Generator, n: int, r: int) -> list[dict]:
    return [{"id": f"m{r}_{j}", "shape": "mesh", "xyz": [2.0 + j, 2.0, 2.0],
             "mesh": (_stl if (r + j) % 2 == 0 else _obj)(rng)} for j in range(n)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=40)
    p.add_argument("--meshes", type=int, default=4, help="meshes added per round")
    p.add_argument("--settle", type=float, default=12.0,
                   help="seconds idle before the last RSS (a trim happens every 10 s)")
    a = p.parse_args()
    rng = np.random.default_rng(7)
    srv = start_server(["--workers", "1"])
    pid = srv.proc.pid
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            start = rss_bytes(pid) / MIB
            series, times = [], []
            for r in range(a.rounds):
                change = {"clear": True, "add": _meshes(rng, a.meshes, r)}
                t = time.perf_counter()
                c.request("scene/apply", change)
                times.append(time.perf_counter() - t)
                series.append(rss_bytes(pid) / MIB)
                print(f"round {r}: {series[-1]:.0f} MiB, apply {times[-1]:.2f} s", flush=True)
            # the scene near its cap of inline meshes, then meshes over it: refused
            # naming the field, before their bytes (no mesh at all) are parsed
            stl = _stl(rng)
            near = MAX_SCENE_MESH_BYTES // (len(stl["data"]) * 3 // 4)
            c.request("scene/apply", {"clear": True, "add": [
                {"id": f"near{j}", "shape": "mesh", "xyz": [2.0, 2.0, 2.0 + j], "mesh": stl}
                for j in range(near)]})
            near_rss = rss_bytes(pid) / MIB
            refused = []
            for r in range(3):
                junk = {"id": f"junk{r}", "shape": "mesh", "xyz": [2.0, 2.0, 2.0],
                        "mesh": {"format": "stl",
                                 "data": base64.b64encode(bytes(2_000_000)).decode()}}
                try:
                    c.request("scene/apply", {"add": [junk]})
                    refused.append("applied")
                except ServiceError as e:
                    refused.append(f"{e.code} {(e.details or {}).get('field')}")
            after_refused = rss_bytes(pid) / MIB
            time.sleep(a.settle)
            settled = rss_bytes(pid) / MIB
            c.request("scene/apply", {"clear": True})
            time.sleep(a.settle)
            cleared = rss_bytes(pid) / MIB
    finally:
        srv.stop()
    print(f"serving process RSS: start {start:.0f} MiB, rounds max {max(series):.0f}, last "
          f"{series[-1]:.0f}, {near} meshes near the cap {near_rss:.0f}, after {len(refused)} refusals {after_refused:.0f}, settled "
          f"{settled:.0f}, scene cleared {cleared:.0f} MiB; refusals {refused}")
    emit("mesh_churn", {"rounds": a.rounds, "meshes_per_round": a.meshes,
                        "rss_start_mib": round(start), "rss_max_mib": round(max(series)),
                        "rss_last_mib": round(series[-1]),
                        "rss_series_mib": [round(x) for x in series],
                        "meshes_near_cap": near, "rss_near_cap_mib": round(near_rss),
                        "rss_after_refusals_mib": round(after_refused),
                        "rss_settled_mib": round(settled), "rss_cleared_mib": round(cleared),
                        "refusals": refused,
                        "apply_median_s": round(float(np.median(times)), 3)})


if __name__ == "__main__":
    main()
