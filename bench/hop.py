"""The service hop: where a plan request's time goes outside the planner, piece by piece.

Starts a real ``arduinobot serve`` (127.0.0.1 on a free port, multicast scouting off) with
the hop probe on (:mod:`arduinobot.service.hoptrace`: the service stamps each stage of every work
request on CLOCK_MONOTONIC, the clock of every process on this host) and sends the bench
scenes' seeded problems (bench/_lib/scenes.py, as ``./dev bench peer`` does) through the
Python client's own steps, stamping the client's side too. Per request, in order:

- ``client_encode``: the request as the client sends it (:func:`arduinobot.client.client.plan_body`:
  the trajectory packed) to JSON (:func:`arduinobot.client.client.encode_body`);
- ``zenoh_in``: the get until the queryable's callback runs;
- ``callback``: the callback (checks, the job queued); ``to_slot``: until a slot thread
  has it; ``pipe``: until the worker has read it; ``decode``: the worker's decode and
  validation;
- ``handler_outside_total``: the handler's time beyond the reply's ``timing.total``
  (building the planner's request); ``encode``: the reply built from the sample arrays
  and encoded (:func:`arduinobot.service.plan.plan_io.plan_reply`; before it, the reply's dict was built
  in the handler: compare the two pieces' sum);
- ``back_to_slot``: until the slot thread has the outcome; ``reply``: until
  ``query.reply`` returned; ``final``: the query finalised;
- ``zenoh_out``: from the reply until the client's get returned (reply and finalisation
  on the wire);
- ``client_decode``, ``client_parse``: the reply's JSON, then the typed, checked
  :class:`~arduinobot.client.replies.PlanReply`;
- ``hop``: end to end (encode to typed reply) minus the reply's ``timing.total``.

Each plan is sent again right after with ``"trajectory_format": "points"`` (a sample object
per point on the wire, the v1 default): its hop is printed beside, the peer of packing.

With ``--kept``, the service keeps bench/scene.py's 20 primitives (a ring out of the arm's
way) in its scene while the plans run: every job is answered against them (the worker
receives the scene once per revision, not with each job).

Also the floor: a bare Zenoh get/reply on loopback (two sessions in this process, a
queryable replying with a plan reply's bytes), back to back and after an idle gap as long
as the median plan's ``timing.total`` (as the service's requests come: a round trip after
a few idle milliseconds costs more, the threads and cores having gone to sleep), and the
reply's size; and the floors of a worker answering its own query, after the same gap:
through the serving peer, and straight to a peer-mode querier (bench/_lib/zenoh_floor.py).

Usage: ./dev bench hop [--n 40] [--model course|shipped] [--scene self] [--workers 2] [--kept]
Prints the split (median and p95 per piece, in ms), then one JSON line.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import orjson

from arduinobot.client.client import PlannerClient, decode_reply, encode_body, plan_body
from arduinobot.client.replies import PlanReply
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.service import hoptrace
from arduinobot.service.process.disk_cache import DiskCache
from bench._lib.peer_models import make_model
from bench._lib.report import emit
from bench._lib.scenes import SCENES, obstacle_dicts, problems
from bench._lib.zenoh_floor import stats, zenoh_floor
from tests.helpers.serve import start_server

ARM = ("joint_1", "joint_2", "joint_3")
#: (piece, from stamp, to stamp); client stamps: c_start, c_sent, c_got, c_decoded, c_parsed
PIECES = (("client_encode", "c_start", "c_sent"), ("zenoh_in", "c_sent", "callback"),
          ("callback", "callback", "queued"), ("to_slot", "queued", "slot"),
          ("pipe", "slot", "w_recv"), ("decode", "w_recv", "w_decoded"),
          ("encode", "w_handled", "w_encoded"), ("back_to_slot", "w_encoded", "done"),
          ("reply", "done", "replied"), ("final", "replied", "final"),
          ("zenoh_out", "replied", "c_got"), ("client_decode", "c_got", "c_decoded"),
          ("client_parse", "c_decoded", "c_parsed"))


def problem_body(names: tuple[str, ...], a: np.ndarray, b: np.ndarray, obstacles: list[dict],
              seed: int) -> dict[str, Any]:
    """bench/peer.py's request: start of every joint, an arm goal, scaling 1.0."""
    return {"start": dict(zip(names, map(float, a))),
            "goal": {"joints": dict(zip(ARM, map(float, b[:3])))},
            "obstacles": obstacles, "planning_time": 1.0, "velocity_scaling": 1.0,
            "acceleration_scaling": 1.0, "seed": seed}


def one(c: PlannerClient, body: dict[str, Any]) -> tuple[dict[str, float], PlanReply, int]:
    """One plan through the client's own steps (:meth:`PlannerClient.plan`: the trajectory
    packed unless ``body`` says otherwise), stamped; and the reply's size [bytes]."""
    st = {"c_start": hoptrace.now()}
    payload = encode_body(plan_body(body))
    key = f"{c.prefix}/plan"
    st["c_sent"] = hoptrace.now()
    replies = c._get(key, payload, c.timeout + 1.0)
    st["c_got"] = hoptrace.now()
    decoded = decode_reply(replies[0], key, c.timeout)
    st["c_decoded"] = hoptrace.now()
    reply = PlanReply.parse(decoded)
    st["c_parsed"] = hoptrace.now()
    ok = replies[0].ok
    return st, reply, 0 if ok is None else len(ok.payload)


def run(args: argparse.Namespace, folder: Path) -> dict[str, Any]:
    model = make_model(args.model, folder / args.model)
    cache = folder / "cache"
    mp = MotionPlanner(model.description, cache=DiskCache(cache))
    names = mp.joint_names
    obs = obstacle_dicts(list(SCENES[args.scene]))
    probs = problems(mp.world(tuple(SCENES[args.scene])), args.n,
                     np.random.default_rng(args.seed))
    trace = folder / "hop.jsonl"
    srv = start_server(["--workers", str(args.workers), *model.serve_args,
                        "--cache-dir", str(cache)], timeout=600,
                       env={**os.environ, hoptrace.ENV: str(trace)})
    rows: list[tuple[dict[str, float], PlanReply, int]] = []
    as_points: list[float] = []
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            if args.kept:
                from bench.scene import objects
                c.request("scene/apply", {"clear": True, "add": objects(meshes=False)})
            for k, (a, b, _) in enumerate(probs[:args.workers * 2]):  # warm: not counted
                one(c, problem_body(names, a, b, obs, 10_000 + k))
            for i, (a, b, _) in enumerate(probs):
                rows.append(one(c, problem_body(names, a, b, obs, i)))
                # the same plan with points on the wire, right after: the peer of packing
                st, reply, _ = one(c, {**problem_body(names, a, b, obs, i),
                                       "trajectory_format": "points"})
                as_points.append(st["c_parsed"] - st["c_start"] - reply.timing["total"])
    finally:
        srv.stop()
    served = {}
    for line in trace.read_text().splitlines():
        rec = orjson.loads(line)
        served[rec["request_id"]] = rec["stamps"]
    pieces: dict[str, list[float]] = {p: [] for p, _, _ in PIECES}
    outside, hop, totals = [], [], []
    for st, reply, _ in rows:
        s = {**st, **served[reply.request_id]}
        for p, a, b in PIECES:
            pieces[p].append(s[b] - s[a])
        total = reply.timing["total"]
        outside.append(s["w_handled"] - s["w_decoded"] - total)
        hop.append(s["c_parsed"] - s["c_start"] - total)
        totals.append(total)
    split = {p: stats(v) for p, v in pieces.items()}
    split["handler_outside_total"] = stats(outside)
    big = orjson.dumps(dict(max(rows, key=lambda r: r[2])[1].raw))
    gap = statistics.median(totals)
    return {"model": args.model, "scene": args.scene, "kept_objects": 20 if args.kept else 0,
            "problems": len(rows),
            "workers": args.workers, "hop": stats(hop), "hop_points": stats(as_points),
            "total": stats(totals),
            "split": split, "reply_bytes_median": statistics.median(n for _, _, n in rows),
            "points_median": statistics.median(len(r.times) for _, r, _ in rows),
            "zenoh_floor": zenoh_floor(big, args.floor_repeats),
            "zenoh_floor_after_gap": zenoh_floor(big, args.floor_repeats // 2, gap=gap),
            # the floors of a worker answering its own query (issue 43, item 3): through
            # the serving peer, and straight from a peer-mode querier
            "zenoh_floor_via_peer_after_gap": zenoh_floor(big, args.floor_repeats // 2,
                                                          gap=gap, route="via_peer"),
            "zenoh_floor_direct_after_gap": zenoh_floor(big, args.floor_repeats // 2,
                                                        gap=gap, route="direct"),
            "load_average": round(os.getloadavg()[0], 2)}


def report(res: dict[str, Any]) -> None:
    kept = f", {res['kept_objects']} objects kept" if res["kept_objects"] else ""
    print(f"{res['model']} / {res['scene']}{kept}: {res['problems']} plans, "
          f"{res['points_median']:.0f} samples and {res['reply_bytes_median']:.0f} reply bytes "
          f"(medians), load average {res['load_average']}")
    order = ["client_encode", "zenoh_in", "callback", "to_slot", "pipe", "decode",
             "handler_outside_total", "encode", "back_to_slot", "reply", "final",
             "zenoh_out", "client_decode", "client_parse"]
    for p in order:
        s = res["split"][p]
        print(f"  {p:22s} median {s['median_ms']:7.3f} ms   p95 {s['p95_ms']:7.3f} ms")
    h, f = res["hop"], res["zenoh_floor"]
    print(f"  hop (end to end - timing.total): median {h['median_ms']:.3f} ms, p95 "
          f"{h['p95_ms']:.3f} ms (target: median <= 1 ms)")
    p = res["hop_points"]
    print(f"  the same plans with points on the wire (trajectory_format \"points\", each "
          f"right after its packed one): hop median {p['median_ms']:.3f} ms, p95 "
          f"{p['p95_ms']:.3f} ms")
    g = res["zenoh_floor_after_gap"]
    print(f"  bare Zenoh get/reply of the largest reply: median {f['median_ms']:.3f} ms, "
          f"p95 {f['p95_ms']:.3f} ms back to back; after an idle gap of the median total: "
          f"median {g['median_ms']:.3f} ms, p95 {g['p95_ms']:.3f} ms")
    v, d = res["zenoh_floor_via_peer_after_gap"], res["zenoh_floor_direct_after_gap"]
    print(f"  the same after the gap, answered by another process (a worker answering its "
          f"own query): through the serving peer median {v['median_ms']:.3f} ms, p95 "
          f"{v['p95_ms']:.3f} ms; straight to a peer-mode querier median "
          f"{d['median_ms']:.3f} ms, p95 {d['p95_ms']:.3f} ms")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=40, help="problems (default 40)")
    ap.add_argument("--model", default="course", choices=("course", "shipped"))
    ap.add_argument("--scene", default="self", choices=tuple(SCENES))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=7, help="problem draws (7: bench/peer's)")
    ap.add_argument("--floor-repeats", type=int, default=200)
    ap.add_argument("--kept", action="store_true",
                    help="keep 20 primitives in the service's scene (bench/scene.py's ring)")
    ap.add_argument("--keep", metavar="DIR",
                    help="generate the model and its cache here and keep them (faster reruns)")
    args = ap.parse_args(argv)
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    set_ompl_log_level("none")
    folder = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-hop-"))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "hop.jsonl").unlink(missing_ok=True)
    try:
        res = run(args, folder)
    finally:
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)
    report(res)
    emit("hop", res)


if __name__ == "__main__":
    main()
