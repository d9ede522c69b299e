"""Soak benchmark: a real `arduinobot serve` under mixed load for minutes, then a crash.

Client threads (each its own Zenoh session) send, in a seeded mix: plans on the benchmark
scenes (bench/_lib/scenes.py), fk and state checks, kept-scene applies (each client
replacing its own box through ``PlannerClient.update``, racing the others), the shipped
tasks.yaml's pick as a task (planned only), and bad inputs (malformed JSON, unknown
fields, out-of-limit joints, oversized payloads) that must come back as coded errors.
Prints throughput, latency percentiles, lost replies (no reply at all, or an unexpected
code: target 0), the resident memory of every serve process (server, forkserver, zygote,
workers) at start and end (target: growth under 5%) and every ``--sample-every`` seconds
in between (the series), and the time from a worker's SIGKILL
to the next successful plan on a one-worker server (median of ``--kills``). Then one
line of JSON. Valid plans that time out (coded TIMEOUT) are counted apart: a few of the
scenes' detours take seconds each, and a shared 2-core machine stretches them.

    ./dev bench soak                      # 10 minutes, 4 clients
    ./dev bench soak --minutes 1 --clients 4 --kills 5
    ./dev bench soak --minutes 2 --kills 0 --memtrace 20  # where memory goes

``--memtrace`` runs the server with its memory probe (src/arduinobot/service/process/memtrace.py: resident set by
kind, Python's traced memory, glibc's heap, live jobs, tracemalloc diffs) and prints it.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import threading
import time
from collections import Counter

import numpy as np

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.client.replies import SceneReply
from arduinobot.service.process.pool import rss_bytes
from bench._lib.report import emit
from bench._lib.scenes import SCENES, obstacle_dicts, problems
from tests.helpers.procs import process_tree, wait_for, wait_for_cpu
from tests.helpers.serve import start_server

#: how long a serve may take to start [s]: on a loaded 2-core machine the planner's build
#: took 70-100 s (the tests' 90 s ran out)
START_WAIT = 300.0
#: bad inputs and the code each must get
BAD = [("plan", b"{not json", "INVALID_REQUEST"),
       ("plan", b'{"goal": {"named": "reach_left"}, "speed": 2}', "INVALID_REQUEST"),
       ("fk", b'{"joints": {"joint_1": 99}}', "INVALID_REQUEST"),
       ("plan", b'{"goal": {"joints": {"joint_1": NaN}}}', "INVALID_REQUEST"),
       ("check", b'{"joints": {"nope": 0.1}}', "INVALID_REQUEST"),
       ("plan", b"[" * 5000 + b"]" * 5000, "INVALID_REQUEST"),
       ("plan", b'{"goal": {"named": "x"}, "pad": "' + b"a" * 300_000 + b'"}',
        "INVALID_REQUEST")]
#: codes a good plan may get on a busy machine without anything being wrong
#: (TIMEOUT too: some detours take seconds, and the machine is shared; counted apart)
PLAN_CODES = {"NO_PATH_FOUND", "TRAJECTORY_FAILED", "BUSY", "TIMEOUT"}


def rss_by_role(server_pid: int, endpoint: str) -> dict[str, tuple[int, int]]:
    """Role -> (processes, resident bytes) over the server's process tree; workers
    replaced during the run are the live ones at the time of the call."""
    with PlannerClient(endpoint, timeout=60) as c:
        h = c.health()
    live = {w["pid"] for w in h["workers"]}
    out: dict[str, tuple[int, int]] = {}
    for p in process_tree(server_pid):
        role = ("server" if p == server_pid else "zygote" if p == h.get("zygote")
                else "workers" if p in live else "forkserver")
        n, b = out.get(role, (0, 0))
        out[role] = (n + 1, b + rss_bytes(p))
    return out


class RssSampler:
    """Every ``every`` seconds [s], the resident set of each role (see
    :func:`rss_by_role`) on a background thread: the series, not only start and end."""

    def __init__(self, server_pid: int, endpoint: str, every: float) -> None:
        self.server_pid, self.endpoint, self.every = server_pid, endpoint, every
        self.series: list[tuple[float, dict[str, tuple[int, int]]]] = []
        self._stop = threading.Event()
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="rss-sampler", daemon=True)

    def __enter__(self) -> RssSampler:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        while True:
            self.series.append((time.monotonic() - self._t0,
                                rss_by_role(self.server_pid, self.endpoint)))
            if self._stop.wait(self.every):
                return

    def role(self, name: str) -> list[tuple[float, float]]:
        """``[(t [s], MiB)]`` of one role."""
        return [(t, by.get(name, (0, 0))[1] / 2**20) for t, by in self.series]


def requests(seed: int) -> list[tuple[str, object, set[str] | None]]:
    """A seeded mix: (kind, body, allowed error codes; None: must succeed)."""
    from arduinobot.description import load_description
    from arduinobot.planner.planning.pipeline import MotionPlanner
    desc = load_description()
    rng = np.random.default_rng(seed)
    mix: list[tuple[str, object, set[str] | None]] = []
    names = desc.robot.actuated_joints
    arm = desc.summary()["groups"][desc.default_group()]
    planner = MotionPlanner(desc)
    for obs in SCENES.values():
        # the service's world: with the ground under the base (scene/ground.py), so the
        # ends drawn are valid where it plans
        w = planner.world(tuple(obs))
        for a, b, _ in problems(w, 12, rng):
            mix.append(("plan", {"start": dict(zip(names, map(float, a))),
                                 # the arm's joints (the gripper is not in the group)
                                 "goal": {"joints": dict(zip(arm, map(float, b)))},
                                 "obstacles": obstacle_dicts(obs), "seed": int(rng.integers(1e6)),
                                 "planning_time": 1.0}, PLAN_CODES))
            mix.append(("fk", {"joints": dict(zip(names, map(float, a)))}, {"BUSY"}))
            mix.append(("check", {"joints": dict(zip(names, map(float, b))),
                                  "obstacles": obstacle_dicts(obs)}, {"BUSY"}))
    for kind, body, code in BAD:
        mix.append((kind, body, {code, "BUSY"}))
    # the kept scene and tasks: a client's own object replaced (its body made per client,
    # see load), the shipped tasks.yaml's pick planned in the kept scene
    mix += [("scene/apply", None, {"BUSY"})] * 6
    mix += [("task", {"number": 1, "trajectories": False}, {"BUSY", "TIMEOUT"})] * 3
    return mix


def scene_change(scene: SceneReply, client: int, n: int) -> dict:
    """Client ``client``'s ``n``-th apply to ``scene``: its box moved (out of every
    scene's way, beyond the arm's reach) by replacing it, through the client's update
    loop."""
    oid = f"soak{client}"
    box = {"id": oid, "shape": "box", "size": [0.05, 0.05, 0.05],
           "xyz": [3.0 + 0.1 * client, 0.01 * (n % 50), 0.5]}
    held = any(o["id"] == oid for o in scene.objects)
    return {"remove": [oid] if held else [], "add": [box]}


def load(endpoint: str, clients: int, seconds: float, seed: int) -> dict:
    mix = requests(seed)
    lat: dict[str, list[float]] = {"plan": [], "fk": [], "check": [], "bad": [],
                                   "scene/apply": [], "task": []}
    outcomes: Counter[str] = Counter()
    unexpected: list[str] = []
    lock = threading.Lock()
    end = time.monotonic() + seconds

    def run(i: int) -> None:
        rng = np.random.default_rng(seed + 1 + i)
        applied = 0
        with PlannerClient(endpoint, timeout=60) as c:
            while time.monotonic() < end:
                kind, body, allowed = mix[int(rng.integers(len(mix)))]
                bad = isinstance(body, bytes)
                t = time.perf_counter()
                try:
                    if kind == "scene/apply":
                        c.update(lambda scene, n=applied: scene_change(scene, i, n))
                        applied += 1
                    elif kind == "task":
                        c.task(1, trajectories=False)
                    else:
                        c.request(kind, body)
                    code = "ok"
                except errors.ServiceUnavailable as e:
                    code = f"LOST({e.reason})"
                except errors.ServiceError as e:
                    code = str(e.code)
                dt = time.perf_counter() - t
                expected = (code == "ok" and not bad) or code in (allowed or set())
                with lock:
                    outcomes[code] += 1
                    if expected:
                        lat["bad" if bad else kind].append(dt)
                    else:
                        unexpected.append(f"{kind} {'bad ' if bad else ''}-> {code}")
    threads = [threading.Thread(target=run, args=(i,)) for i in range(clients)]
    t0 = time.monotonic()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return {"elapsed": time.monotonic() - t0, "latency": lat, "outcomes": outcomes,
            "unexpected": unexpected}


def recovery(kills: int) -> list[float]:
    """Seconds from a busy worker's SIGKILL to the next successful plan (1 worker)."""
    long_plan = {"start": {"joint_1": -1.2, "joint_2": 1.2, "joint_3": 0.3},
                 "goal": {"joints": {"joint_1": 1.2, "joint_2": 1.2, "joint_3": 0.3}},
                 "obstacles": [{"id": "ball", "shape": "sphere", "radius": 0.2,
                                "xyz": [-0.15, -0.49, 2.33]}],
                 "planner": "RRTstar", "planning_time": 10.0, "seed": 1}
    short = {"goal": {"named": "reach_left"}, "seed": 1}
    srv = start_server(["--workers", "1"], timeout=START_WAIT)
    out = []
    try:
        with PlannerClient(srv.endpoint, timeout=60) as c:
            for _ in range(kills):
                box: dict = {}
                t = threading.Thread(target=lambda b=box: b.update(
                    r=_try(lambda: c.plan(long_plan))))
                t.start()
                w = wait_for(lambda: (x := c.health()["workers"][0])["busy"] and x,
                             every=0.02, what="the worker busy")
                # well into its 10 s of planning: it has spent CPU on the job (an idle
                # worker spends none), so the kill costs that request
                wait_for_cpu(w["pid"], 0.2)
                t_kill = time.monotonic()
                os.kill(w["pid"], signal.SIGKILL)
                while isinstance(_try(lambda: c.plan(short)), Exception):
                    pass
                out.append(time.monotonic() - t_kill)
                t.join()
                if not isinstance(box["r"], errors.InternalError):
                    raise SystemExit(f"the killed request got {type(box['r']).__name__}, "
                                     "not INTERNAL")
    finally:
        srv.stop()
    return out


def _try(fn):
    try:
        return fn()
    except errors.ServiceError as e:
        return e


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--clients", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--kills", type=int, default=5)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--warmup", type=float, default=30.0,
                    help="seconds of load before the RSS baseline [s]")
    ap.add_argument("--memtrace", type=float, default=0.0,
                    help="run the server with its memory probe every this many seconds "
                    "(src/arduinobot/service/process/memtrace.py) and print what it logged [s]")
    ap.add_argument("--sample-every", type=float, default=10.0,
                    help="seconds between RSS samples during the run [s]")
    a = ap.parse_args()
    if a.memtrace:
        os.environ["ARDUINOBOT_MEMTRACE"] = str(a.memtrace)  # the server inherits it
    srv = start_server(["--workers", str(a.workers), "--queue", str(4 * a.clients)],
                       timeout=START_WAIT)
    try:
        with PlannerClient(srv.endpoint, timeout=60) as c:
            c.plan(goal={"named": "reach_left"}, seed=1)  # every kernel warm
        rss_cold = rss_by_role(srv.proc.pid, srv.endpoint)
        # a short run first: allocators, caches and Zenoh buffers settle before the
        # baseline is taken
        load(srv.endpoint, a.clients, a.warmup, a.seed + 100)
        rss0 = rss_by_role(srv.proc.pid, srv.endpoint)
        with RssSampler(srv.proc.pid, srv.endpoint, a.sample_every) as sampler:
            res = load(srv.endpoint, a.clients, 60 * a.minutes, a.seed)
        rss1 = rss_by_role(srv.proc.pid, srv.endpoint)
        with PlannerClient(srv.endpoint, timeout=60) as c:
            counters = c.health()["counters"]
    finally:
        code = srv.stop(signal.SIGTERM)
    rec = recovery(a.kills) if a.kills else []
    n = sum(res["outcomes"].values())
    every = [x for v in res["latency"].values() for x in v]
    pct = {q: 1000 * float(np.percentile(every, q)) for q in (50, 95, 99)} if every else {}
    plans = res["latency"]["plan"]
    lost = sum(v for k, v in res["outcomes"].items() if k.startswith("LOST"))
    print(f"soak: {a.minutes:g} min, {a.clients} clients, {a.workers} workers, "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (shared machine)")
    print(f"requests {n} ({n / res['elapsed']:.1f}/s); outcomes {dict(res['outcomes'])}")
    if pct:
        print(f"latency all kinds p50 {pct[50]:.1f} ms, p95 {pct[95]:.1f} ms, p99 "
              f"{pct[99]:.1f} ms; plans p50 {1000 * statistics.median(plans):.1f} ms"
              if plans else "")
    print(f"lost replies {lost}, unexpected codes {len(res['unexpected'])} (target 0 and 0)"
          + (f": {Counter(res['unexpected']).most_common(5)}" if res["unexpected"] else ""))
    timeouts = res["outcomes"].get("TIMEOUT", 0)
    print(f"coded TIMEOUTs of valid plans {timeouts} (slow detours on a loaded machine)")
    for role in sorted(rss1):
        (_, b0), (n1, b1), (_, bc) = rss0.get(role, (0, 0)), rss1[role], \
            rss_cold.get(role, (0, 0))
        print(f"  rss {role:10s} ({n1} processes): {bc / 2**20:.0f} MiB cold, "
              f"{b0 / 2**20:.0f} after warm-up -> {b1 / 2**20:.0f} MiB at the end "
              f"({100 * (b1 - b0) / b0:+.1f}%)")
    total0 = sum(b for _, b in rss0.values())
    total1 = sum(b for _, b in rss1.values())
    growth = 100 * (total1 - total0) / total0
    print(f"rss all serve processes {total0 / 2**20:.0f} -> {total1 / 2**20:.0f} MiB "
          f"({growth:+.1f}%, target < 5%); server counters {counters}; exit code {code}")
    for role in ("server", "workers", "zygote"):
        print(f"  rss {role} every {a.sample_every:g} s [MiB]: "
              + " ".join(f"{mib:.0f}" for _, mib in sampler.role(role)))
    for line in (ln for ln in srv.stderr_lines if "memtrace:" in ln):
        print("  server " + line.split("memtrace:", 1)[1].rstrip())
    if rec:
        print(f"recovery after a worker SIGKILL (1 worker, next plan ok): median "
              f"{1000 * statistics.median(rec):.0f} ms, all {[round(1000 * r) for r in rec]} ms")
    emit("soak", {"minutes": a.minutes, "clients": a.clients,
                  "requests": n, "per_s": round(n / res["elapsed"], 2),
                  **{f"p{q}_ms": round(v, 1) for q, v in pct.items()},
                  "lost": lost, "unexpected": len(res["unexpected"]),
                  "timeouts": timeouts,
                  "rss_start_mib": round(total0 / 2**20), "rss_end_mib": round(total1 / 2**20),
                  "rss_growth_pct": round(growth, 2),
                  "rss_server_series_mib": [round(m) for _, m in sampler.role("server")],
                  "recovery_median_ms": round(1000 * statistics.median(rec)) if rec else None,
                  "load_average": round(os.getloadavg()[0], 2)})


if __name__ == "__main__":
    main()
