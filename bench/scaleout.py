"""Scale-out benchmark: throughput of 1, 2 and 4 `arduinobot serve` instances behind one
router, with clients that spread by liveliness and load (``PlannerClient(spread=True)``).

Starts a router (``python -m arduinobot.service.router``) and the instances (``--mode client
--connect <router>``, each ``--workers W``) on loopback, multicast scouting off. The same
clients (threads, each with its own session) send the same plans to every setup.
Prints a table, then one line of JSON. On a machine with fewer cores than instances x
workers, the instances share the cores: the table says what this machine allows.

    ./dev bench scaleout                      # 1, 2, 4 instances; 8 clients x 6 plans
    ./dev bench scaleout --clients 16 --requests 40 --rounds 3 --plain
"""

from __future__ import annotations

import argparse
import os
import threading
import time
from collections import Counter

from arduinobot.client.client import PlannerClient
from bench._lib.report import emit
from tests.helpers.procs import stop_processes
from tests.helpers.serve import Server, free_port, launch_serves
from tests.helpers.zrouter import start_router

# about 2 s of motion at 100 Hz (base swing from reach_right to reach_left); seeds vary
REQUEST = {"start": {"joint_1": -1.2, "joint_2": 0.5, "joint_3": 0.9},
           "goal": {"named": "reach_left"}, "velocity_scaling": 0.2,
           "acceleration_scaling": 0.13, "sample_rate": 100}


def start_instances(router: str, n: int, workers: int) -> list[Server]:
    """``n`` instances started at once (they load in parallel), ready when returned."""
    args = ["--mode", "client", "--connect", router, "--workers", str(workers), "--queue",
            "64", "--no-robot"]
    return launch_serves([args] * n, timeout=300)


def run(router: str, clients: int, requests: int, *, spread: bool) -> dict[str, object]:
    """``clients`` threads, each its own session, ``requests`` plans each."""
    sessions = [PlannerClient(router, spread=spread, timeout=120) for _ in clients * [None]]
    latencies: list[float] = []
    served: Counter[str] = Counter()
    errors: Counter[str] = Counter()
    lock = threading.Lock()

    def client(i: int, c: PlannerClient) -> None:
        for k in range(requests):
            t = time.perf_counter()
            try:
                res = c.plan(REQUEST, seed=1000 * i + k)
            except Exception as e:  # noqa: BLE001 -- counted and reported, the run goes on
                with lock:
                    errors[type(e).__name__] += 1
                continue
            dt = time.perf_counter() - t
            with lock:
                latencies.append(dt)
                served[res.request_id.split("-")[0]] += 1

    try:
        for c in sessions:  # discovery and a warm connection before the clock starts
            c.instances(refresh=True)
        threads = [threading.Thread(target=client, args=(i, c)) for i, c in
                   enumerate(sessions)]
        t0 = time.perf_counter()
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        wall = time.perf_counter() - t0
    finally:
        for c in sessions:
            c.close()
    lat = sorted(latencies)
    return {"plans_per_s": len(lat) / wall, "ok": len(lat), "errors": dict(errors),
            "p50_ms": 1000 * lat[len(lat) // 2] if lat else None,
            "p95_ms": 1000 * lat[int(0.95 * (len(lat) - 1))] if lat else None,
            "share": sorted(served.values(), reverse=True)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--instances", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--workers", type=int, default=1, help="workers per instance (1)")
    ap.add_argument("--clients", type=int, default=8, help="concurrent clients (8)")
    ap.add_argument("--requests", type=int, default=6, help="plans per client per round (6)")
    ap.add_argument("--rounds", type=int, default=1, help="rounds per setup; median (1)")
    ap.add_argument("--plain", action="store_true",
                    help="also measure clients without spread (the shared key: zenoh "
                    "picks one instance)")
    a = ap.parse_args()
    router = f"tcp/127.0.0.1:{free_port()}"
    zrouter = start_router(router)
    rows = []
    try:
        for n in a.instances:
            t = time.perf_counter()
            servers = start_instances(router, n, a.workers)
            started = time.perf_counter() - t
            try:
                modes = [True, False] if a.plain else [True]
                for spread in modes:
                    with PlannerClient(router, timeout=120) as warm:  # first plans compile
                        for inst in warm.instances(refresh=True):
                            warm.plan(REQUEST, seed=0, instance=inst)
                    results = [run(router, a.clients, a.requests, spread=spread)
                               for _ in range(a.rounds)]
                    best = sorted(results, key=lambda r: r["plans_per_s"])[len(results) // 2]
                    rows.append({"instances": n, "workers": n * a.workers,
                                 "spread": spread, "start_s": round(started, 1),
                                 "rates": [round(r["plans_per_s"], 2) for r in results],
                                 **best})
            finally:
                stop_processes((s.proc for s in servers), timeout=60)
    finally:
        zrouter.stop(timeout=60)
    base = next(r["plans_per_s"] for r in rows if r["spread"])
    print(f"{os.cpu_count()} cores; {a.clients} clients x {a.requests} plans x "
          f"{a.rounds} round(s); load average now {os.getloadavg()[0]:.1f}")
    print("instances  workers  client   plans/s  vs 1   p50 ms   p95 ms  plans per instance"
          "  errors")
    for r in rows:
        print(f"{r['instances']:>9}  {r['workers']:>7}  {'spread' if r['spread'] else 'plain':>6}"
              f"  {r['plans_per_s']:>8.2f}  x{r['plans_per_s'] / base:.2f}  "
              f"{r['p50_ms']:>7.0f}  {r['p95_ms']:>7.0f}  {str(r['share']):<18}  "
              f"{r['errors'] or 0}")
    emit("scaleout", {"cores": os.cpu_count(), "clients": a.clients,
                      "requests": a.requests, "rounds": a.rounds,
                      "rows": [{k: (round(v, 2) if isinstance(v, float) else v)
                                for k, v in r.items()} for r in rows]})


if __name__ == "__main__":
    main()
