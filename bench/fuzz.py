"""Fuzz benchmark: hostile requests against a real `arduinobot serve`.

Starts `arduinobot serve` (2 workers, loopback, multicast scouting off) and sends
generated hostile requests from several client threads: mutations of valid
plan/fk/ik/check requests, random bytes, deep nesting, huge element counts, extreme
numbers, wrong types, unicode keys, oversized payloads; every ``--valid-every``-th case
is a valid request, which must succeed. Counts the replies by error code, INTERNAL
replies, replies without a code, missing replies, server crashes (process exit) and
failed valid requests. Targets: 100 % coded, 0 INTERNAL, 0 missing, 0 crashes, every
valid request answered. Prints figures, then one line of JSON; exits 1 if a target is
missed.

    ./dev bench fuzz                      # 100,000 cases
    ./dev bench fuzz --cases 5000         # a quick run
"""

from __future__ import annotations

import argparse
import collections
import json
import signal
import sys
import threading
import time
from typing import Any

import zenoh

from arduinobot.contract.zconfig import zenoh_config
from bench._lib.fuzz_cases import KINDS, VALID, Generator
from bench._lib.report import emit
from tests.helpers.serve import start_server

CODES = {"INVALID_REQUEST", "START_IN_COLLISION", "GOAL_IN_COLLISION", "GOAL_OUT_OF_REACH",
         "NO_PATH_FOUND", "TRAJECTORY_FAILED", "INVALID_LIMITS", "LINE_INTERRUPTED",
         "ORIENTATION_NOT_CONTROLLABLE", "TIMEOUT", "BUSY", "RESOURCE_LIMIT", "SHUTTING_DOWN"}

# -- the run ---------------------------------------------------------------------------

class Tally:
    """Counts shared by the client threads."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.codes: collections.Counter[str] = collections.Counter()
        self.categories: collections.Counter[str] = collections.Counter()
        self.ok = 0
        self.internal: list[dict[str, Any]] = []
        self.uncoded: list[dict[str, Any]] = []
        self.missing: list[dict[str, Any]] = []
        self.valid_sent = 0
        self.valid_failed: list[dict[str, Any]] = []
        self.done = 0


def _classify(replies: list[Any]) -> tuple[str, str]:
    """('ok', '') | ('coded', code) | ('uncoded', text) | ('missing', why)."""
    if not replies:
        return "missing", "no reply"
    reply = replies[0]
    if reply.ok is not None:
        return "ok", ""
    text = reply.err.payload.to_bytes().decode("utf-8", "replace")
    if text == "Timeout":
        return "missing", "zenoh timeout"
    try:
        code = json.loads(text)["error"]["code"]
    except (ValueError, KeyError, TypeError):
        return "uncoded", text[:200]
    return "coded", str(code)


def client_thread(endpoint: str, prefix: str, cases: int, seed: int, valid_every: int,
                  tally: Tally, wait: float, stop: threading.Event) -> None:
    gen = Generator(seed)
    cfg = zenoh_config(mode="client", connect=[endpoint], listen=[])
    with zenoh.open(cfg) as session:
        valid_i = 0
        for i in range(cases):
            if stop.is_set():
                return
            if valid_every and i % valid_every == valid_every - 1:
                kind = KINDS[valid_i % len(KINDS)]
                body = VALID[kind][(valid_i // len(KINDS)) % len(VALID[kind])]
                valid_i += 1
                category, payload, is_valid = "valid", json.dumps(body).encode(), True
            else:
                category, kind, payload = gen.case()
                is_valid = False
            replies = list(session.get(f"{prefix}/{kind}", payload=payload, timeout=wait))
            verdict, what = _classify(replies)
            record = {"kind": kind, "category": category, "payload": payload[:300].decode(
                "utf-8", "replace"), "what": what}
            with tally.lock:
                tally.done += 1
                tally.categories[category] += 1
                if is_valid:
                    tally.valid_sent += 1
                    if verdict != "ok":
                        tally.valid_failed.append(record)
                if verdict == "ok":
                    tally.ok += 1
                elif verdict == "coded":
                    tally.codes[what] += 1
                    if what == "INTERNAL" or what not in CODES:
                        tally.internal.append(record)
                elif verdict == "uncoded":
                    tally.uncoded.append(record)
                else:
                    tally.missing.append(record)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=100_000, help="hostile and valid requests")
    ap.add_argument("--threads", type=int, default=8, help="client threads")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--queue", type=int, default=64, help="serve --queue")
    ap.add_argument("--valid-every", type=int, default=50,
                    help="every N-th request of a thread is a valid one (0: none)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--wait", type=float, default=120.0,
                    help="how long a request may take before it counts as missing [s]")
    ap.add_argument("--show", type=int, default=5, help="failing cases printed per kind")
    args = ap.parse_args()

    srv = start_server(["--workers", str(args.workers), "--queue", str(args.queue)])
    proc, endpoint, lines = srv.proc, srv.endpoint, srv.stderr_lines
    tally = Tally()
    stop = threading.Event()
    per = [args.cases // args.threads + (1 if i < args.cases % args.threads else 0)
           for i in range(args.threads)]
    t0 = time.perf_counter()
    threads = [threading.Thread(target=client_thread,
                                args=(endpoint, "arduinobot", n, args.seed * 1000 + i,
                                      args.valid_every, tally, args.wait, stop), daemon=True)
               for i, n in enumerate(per)]
    for t in threads:
        t.start()
    crashed_at = None
    last = time.perf_counter()
    while any(t.is_alive() for t in threads):
        for t in threads:
            t.join(1.0)
        if proc.poll() is not None and crashed_at is None:
            crashed_at = tally.done
            stop.set()
        if time.perf_counter() - last > 30:
            last = time.perf_counter()
            print(f"  {tally.done} cases, {tally.done / (last - t0):.0f}/s", flush=True)
    elapsed = time.perf_counter() - t0
    crashes = 0 if crashed_at is None else 1
    exit_code = proc.poll()
    if exit_code is None:
        exit_code = srv.stop(signal.SIGINT, timeout=30)
    worker_deaths = sum(1 for ln in lines if "died" in ln or "replac" in ln.lower())
    tracebacks = sum(1 for ln in lines if ln.startswith("Traceback"))

    replies = tally.ok + sum(tally.codes.values()) + len(tally.uncoded)
    errors = sum(tally.codes.values()) + len(tally.uncoded)
    coded = sum(n for c, n in tally.codes.items() if c in CODES)
    print(f"fuzz: {tally.done} cases in {elapsed:.1f} s ({tally.done / elapsed:.0f}/s), "
          f"{args.threads} client threads, serve --workers {args.workers}")
    print(f"  categories: {dict(sorted(tally.categories.items()))}")
    print(f"  succeeded: {tally.ok}; error replies: {errors}, coded: {coded} "
          f"({100.0 * coded / max(errors, 1):.3f} %)")
    print(f"  codes: {dict(tally.codes.most_common())}")
    print(f"  INTERNAL: {len(tally.internal)}, uncoded: {len(tally.uncoded)}, "
          f"missing: {len(tally.missing)}, crashes: {crashes}"
          + (f" (after {crashed_at} cases)" if crashed_at is not None else ""))
    print(f"  valid requests: {tally.valid_sent} sent, {len(tally.valid_failed)} failed")
    print(f"  server: exit code {exit_code} after SIGINT, worker deaths/replacements in its "
          f"log: {worker_deaths}, tracebacks: {tracebacks}")
    for name, rows in (("INTERNAL", tally.internal), ("uncoded", tally.uncoded),
                       ("missing", tally.missing), ("valid failed", tally.valid_failed)):
        for row in rows[:args.show]:
            print(f"  {name}: {json.dumps(row, ensure_ascii=True)[:500]}")
    if tracebacks:
        first = next(i for i, ln in enumerate(lines) if ln.startswith("Traceback"))
        print("  first traceback in the server log:\n    " + "\n    ".join(lines[first:first + 25]))
    summary = {"cases": tally.done, "seconds": round(elapsed, 1),
               "rate": round(tally.done / elapsed, 1), "threads": args.threads,
               "workers": args.workers, "succeeded": tally.ok, "error_replies": errors,
               "coded": coded, "codes": dict(tally.codes), "internal": len(tally.internal),
               "uncoded": len(tally.uncoded), "missing": len(tally.missing),
               "crashes": crashes, "valid_sent": tally.valid_sent,
               "valid_failed": len(tally.valid_failed), "server_exit": exit_code,
               "categories": dict(tally.categories)}
    emit("fuzz", summary)
    ok = (not tally.internal and not tally.uncoded and not tally.missing and not crashes
          and not tally.valid_failed and replies == tally.done)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
