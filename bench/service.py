"""Service benchmark: latency through Zenoh against the same plan in-process, and
throughput of concurrent clients with 1 worker against N workers.

Starts `arduinobot serve` subprocesses on free loopback ports (multicast scouting off).
Prints figures, then one line of JSON.

    ./dev bench service [--repeats 30] [--clients 4] [--requests 40]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import threading
import time

from arduinobot.client.client import PlannerClient
from arduinobot.contract import wire
from arduinobot.description import load_description
from arduinobot.service.plan.handlers import Handlers
from bench._lib.report import emit
from tests.helpers.serve import Server, start_server

# A 100 Hz trajectory of about 2 s (base swing from reach_right to reach_left).
REQUEST = {"start": {"joint_1": -1.2, "joint_2": 0.5, "joint_3": 0.9},
           "goal": {"named": "reach_left"}, "seed": 1, "velocity_scaling": 0.2,
           "acceleration_scaling": 0.13, "sample_rate": 100}


def serve(workers: int) -> Server:
    return start_server(["--workers", str(workers), "--queue", "64"], timeout=300)


def latency(repeats: int) -> dict[str, float]:
    """Interleaved: each round plans in-process, then through Zenoh, so machine load
    hits both alike. ``overhead_paired`` is each service round trip minus the planner's
    own solve time reported in that reply (timing.total): transport, JSON, queueing."""
    handlers = Handlers(load_description())
    handlers.warm_up()
    payload = json.dumps(REQUEST)
    local, remote, paired = [], [], []
    srv = serve(1)
    try:
        with PlannerClient(srv.endpoint) as c:
            for i in range(repeats + 3):
                t = time.perf_counter()
                body = handlers.plan(wire.decode("plan", payload))
                t_local = time.perf_counter() - t
                t = time.perf_counter()
                res = c.plan(REQUEST)
                t_remote = time.perf_counter() - t
                if i >= 3:  # warm-up rounds
                    local.append(t_local)
                    remote.append(t_remote)
                    paired.append(t_remote - res.timing["total"])
    finally:
        srv.stop(timeout=30)
    if res.positions[-1].tolist() != body["trajectory"]["points"][-1]["positions"]:
        raise SystemExit("the service and the in-process plan differ")
    ml, mr = statistics.median(local), statistics.median(remote)
    return {"duration_s": body["duration"], "points": len(body["trajectory"]["points"]),
            "reply_bytes": len(wire.encode(body)), "in_process_median_ms": 1000 * ml,
            "service_median_ms": 1000 * mr, "overhead_median_ms": 1000 * (mr - ml),
            "overhead_paired_median_ms": 1000 * statistics.median(paired)}


def rate(endpoint: str, clients: int, requests: int) -> float:
    """Plans per second with ``clients`` threads sharing ``requests`` plans."""
    with PlannerClient(endpoint) as c:
        c.request("plan", REQUEST)  # warm
        per = requests // clients

        def run() -> None:
            for _ in range(per):
                c.request("plan", REQUEST)
        threads = [threading.Thread(target=run) for _ in range(clients)]
        t = time.perf_counter()
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        return per * clients / (time.perf_counter() - t)


def throughput(workers: int, clients: int, requests: int, rounds: int) -> tuple[float, float]:
    """Median rates of a 1-worker and a ``workers``-worker server, measured in
    alternation so that drifting machine load hits both alike."""
    one, many = serve(1), serve(workers)
    try:
        ones, manys = [], []
        for _ in range(rounds):
            ones.append(rate(one.endpoint, clients, requests))
            manys.append(rate(many.endpoint, clients, requests))
    finally:
        one.stop(timeout=30)
        many.stop(timeout=30)
    return statistics.median(ones), statistics.median(manys)


def main() -> None:
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    set_ompl_log_level("none")
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--clients", type=int, default=4)
    ap.add_argument("--requests", type=int, default=48)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    a = ap.parse_args()
    lat = latency(a.repeats)
    print(f"plan of {lat['duration_s']:.2f} s at 100 Hz ({lat['points']} points, "
          f"{lat['reply_bytes']} reply bytes)")
    print(f"in-process median {lat['in_process_median_ms']:.2f} ms; through zenoh "
          f"{lat['service_median_ms']:.2f} ms (typed client result)")
    print(f"overhead: difference of medians {lat['overhead_median_ms']:.2f} ms; paired "
          f"(round trip - solve time in the reply) {lat['overhead_paired_median_ms']:.2f} ms; "
          "target <= 2 ms")
    one, many = throughput(a.workers, a.clients, a.requests, a.rounds)
    print(f"throughput with {a.clients} concurrent clients: 1 worker {one:.2f} plans/s, "
          f"{a.workers} workers {many:.2f} plans/s, x{many / one:.2f} (target >= 1.8 on 2 "
          f"cores; load average {os.getloadavg()[0]:.1f})")
    emit("service", {**{k: round(v, 4) for k, v in lat.items()},
                     "throughput_1_worker": round(one, 3),
                     f"throughput_{a.workers}_workers": round(many, 3),
                     "speedup": round(many / one, 3), "clients": a.clients,
                     "load_average": round(os.getloadavg()[0], 2)})


if __name__ == "__main__":
    main()
