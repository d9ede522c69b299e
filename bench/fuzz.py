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
import random
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from bench._lib.report import emit
from service import caps
from service.zconfig import zenoh_config
from tests.helpers.json_paths import json_get, json_paths
from tests.helpers.serve import start_server

KINDS = ("plan", "fk", "ik", "check")
CODES = {"INVALID_REQUEST", "START_IN_COLLISION", "GOAL_IN_COLLISION", "GOAL_OUT_OF_REACH",
         "NO_PATH_FOUND", "TRAJECTORY_FAILED", "INVALID_LIMITS", "LINE_INTERRUPTED",
         "ORIENTATION_NOT_CONTROLLABLE", "TIMEOUT", "BUSY", "RESOURCE_LIMIT", "SHUTTING_DOWN"}

# Valid requests: the seeds of mutations, and the interleaved requests that must succeed
# (plans short and seeded, so they succeed every time).
VALID: dict[str, list[dict[str, Any]]] = {
    "plan": [
        {"goal": {"named": "reach_left"}, "seed": 1},
        {"goal": {"joints": {"joint_1": 0.3, "joint_2": -0.2}}, "start": {"joint_3": 0.1},
         "planning_time": 0.5, "seed": 3, "sample_rate": 50, "profile": "time_optimal"},
        {"goal": {"joints": {"joint_1": -0.4}}, "group": "arm", "velocity_scaling": 0.5,
         "acceleration_scaling": 0.25, "seed": 2,
         "obstacles": [{"id": "ball", "shape": "sphere", "radius": 0.1, "xyz": [2, 2, 2]},
                       {"id": "table", "shape": "box", "size": [0.5, 0.5, 0.1],
                        "xyz": [0, -2, 0.5], "rpy": [0, 0, 0.3]},
                       {"id": "post", "shape": "cylinder", "radius": 0.05, "length": 1,
                        "xyz": [-2, 0, 0]}]},
        {"goal": {"named": "home"}, "start": {"joint_1": 0.3},
         "start_velocity": {"joint_1": 0.1, "joint_2": 0.1},
         "start_acceleration": {"joint_2": 0.2}, "seed": 4},
    ],
    "fk": [{"joints": {"joint_1": 0.5}}, {"joints": {}, "links": ["base_link"]}, {}],
    "ik": [{"position": [0.0, 1.0, 1.2]}],
    "check": [{"joints": {"joint_2": 0.4}},
              {"joints": {"joint_1": 0.1}, "padding": 0.02,
               "obstacles": [{"id": "b", "shape": "sphere", "radius": 0.2,
                              "xyz": [0, 1, 1.6]}]}],
}

NUMBERS = [0, -0.0, 1, -1, 5e-324, 1e-300, -1e-300, 1e-12, 1e-8, 1e300, -1e300,
           1.7976931348623157e308, 2**53 + 1, 2**63 - 1, -(2**63), 2**64 - 1, 4294967296,
           0.5, 7.0, 1000.0, 1000.0000001, 60.0, 0.01, 0.0099999, 100.0, -100.0, 1e-7, 3.14159]
STRINGS = ["", " ", "home", "reach_left", "joint_1", "joint_5", "base_link", "\u0000",
           "\u202e", "é", "日本", "\U0001f916", "a" * 64, "a" * 65, "x" * 2000, "all", "arm",
           "gripper", "RRTConnect", "PRM", "box", "mesh", "../../etc/passwd", "$*", "**"]
# numbers written as text: what json.dumps cannot produce
RAW_NUMBERS = ["1e309", "-1e309", "1" * 400, "NaN", "Infinity", "-Infinity", "-0", "1E-400",
               "0.000000000000000000000000000000001", "123456789012345678901234567890"]


class Generator:
    """Hostile payloads, reproducible from a seed."""

    def __init__(self, seed: int) -> None:
        self.r = random.Random(seed)

    # -- values ------------------------------------------------------------------------
    def scalar(self) -> Any:
        r = self.r
        pick = r.random()
        if pick < 0.35:
            return r.choice(NUMBERS)
        if pick < 0.55:
            return r.uniform(-3, 3)
        if pick < 0.75:
            return r.choice(STRINGS)
        if pick < 0.85:
            return self.unicode(r.randint(0, 12))
        return r.choice([None, True, False, r.randint(-10**6, 10**6)])

    def value(self, depth: int = 0) -> Any:
        r = self.r
        if depth > 3 or r.random() < 0.6:
            return self.scalar()
        if r.random() < 0.5:
            return [self.value(depth + 1) for _ in range(r.randint(0, 5))]
        return {self.key(): self.value(depth + 1) for _ in range(r.randint(0, 5))}

    def unicode(self, n: int) -> str:
        r = self.r
        pools = [(0x20, 0x7e), (0xa0, 0x24f), (0x370, 0x3ff), (0x4e00, 0x4fff),
                 (0x1f300, 0x1f6ff), (0x200b, 0x202e), (0xfff0, 0xfffd)]
        out = []
        for _ in range(n):
            lo, hi = r.choice(pools)
            out.append(chr(r.randint(lo, hi)))
        return "".join(out)

    def key(self) -> str:
        r = self.r
        return r.choice([r.choice(STRINGS), self.unicode(r.randint(1, 10)),
                         r.choice(["goal", "start", "joints", "obstacles", "named", "id",
                                   "position", "radius", "size", "links", "padding"])])

    # -- cases -------------------------------------------------------------------------
    def case(self) -> tuple[str, str, bytes]:
        """(category, kind, payload)."""
        r = self.r
        kind = r.choice(KINDS)
        cats: list[tuple[float, str, Callable[[str], bytes]]] = [
            (0.40, "mutation", self.mutation), (0.08, "same_type", self.same_type),
            (0.10, "random_bytes", self.random_bytes), (0.08, "deep_nesting", self.deep),
            (0.05, "huge_counts", self.huge_counts), (0.10, "extreme_numbers", self.extreme),
            (0.09, "wrong_types", self.wrong_types), (0.09, "unicode_keys", self.unicode_keys),
            (0.01, "oversized", self.oversized)]
        x = r.random() * sum(w for w, _, _ in cats)
        for w, name, make in cats:
            x -= w
            if x <= 0:
                return name, kind, make(kind)
        return cats[0][1], kind, cats[0][2](kind)

    def base(self, kind: str) -> Any:
        return json.loads(json.dumps(self.r.choice(VALID[kind])))  # a deep copy

    def mutation(self, kind: str) -> bytes:
        value = self.base(kind)
        for _ in range(self.r.randint(1, 3)):
            value = self._mutate_once(value)
        return _dumps(value)

    def same_type(self, kind: str) -> bytes:
        """Leaves replaced by values of their own type: gets past the schema more often."""
        value = self.base(kind)
        leaves = [p for p in json_paths(value) if not isinstance(json_get(value, p), (dict, list))]
        for _ in range(self.r.randint(1, 2)):
            if not leaves:
                break
            path = self.r.choice(leaves)
            old = json_get(value, path)
            if isinstance(old, (int, float)) and not isinstance(old, bool):
                new: Any = self.r.choice([self.r.choice(NUMBERS), self.r.uniform(-2, 2),
                                          self.r.uniform(-10, 10)])
            elif isinstance(old, str):
                new = self.r.choice([self.r.choice(STRINGS), self.unicode(5)])
            else:
                new = self.scalar()
            value = _set(value, path, new)
        return _dumps(value)

    def _mutate_once(self, value: Any) -> Any:
        r = self.r
        paths = json_paths(value)
        path = r.choice(paths)
        op = r.choice(["replace", "replace", "delete", "add", "duplicate"])
        if op == "replace" or not path:
            return _set(value, path, self.value())
        if op == "delete":
            parent = json_get(value, path[:-1])
            if isinstance(parent, dict):
                parent.pop(path[-1], None)
            else:
                del parent[path[-1]]
            return value
        target = json_get(value, path[:-1])
        if op == "add" and isinstance(target, dict):
            target[self.key()] = self.value()
        elif isinstance(target, list):
            target.extend([target[path[-1]]] * r.randint(1, 300))
        elif isinstance(target, dict):
            target[path[-1]] = [json_get(value, path)] * r.randint(1, 300)
        return value

    def random_bytes(self, kind: str) -> bytes:
        r = self.r
        n = r.choice([0, 1, 2, 8, 64, 512, 4096])
        if r.random() < 0.5:
            return bytes(r.getrandbits(8) for _ in range(n))
        # JSON-ish noise: brackets, quotes, digits, escapes
        return "".join(r.choice('{}[]":,0123456789.eE-+ \\u"tfnal') for _ in range(n)).encode()

    def deep(self, kind: str) -> bytes:
        r = self.r
        depth = r.choice([caps.MAX_DEPTH, caps.MAX_DEPTH + 1, 100, 1023, 1025, 5000, 60_000])
        opener, closer = r.choice([("[", "]"), ('{"goal":', "}"), ('{"a":[', "]}")])
        body = opener * depth + "0" + (closer * depth if r.random() < 0.8 else "")
        wrap = r.random() < 0.5
        return (f'{{"goal": {{"named": "home"}}, "obstacles": {body}}}' if wrap else body).encode()

    def huge_counts(self, kind: str) -> bytes:
        r = self.r
        n = r.choice([caps.MAX_ITEMS, caps.MAX_ITEMS + 1, 5000, 60_000])
        elem = r.choice(['1', '{}', '[]', '"x"', '{"id":"a","shape":"sphere","radius":0.1}'])
        field = r.choice(["obstacles", "links", "position"])
        if r.random() < 0.5:
            arr = "[" + ",".join([elem] * n) + "]"
            body = f'{{"goal": {{"named": "home"}}, "{field}": {arr}}}'
        else:
            members = ",".join(f'"j{i}": 0' for i in range(n))
            body = f'{{"goal": {{"named": "home"}}, "joints": {{{members}}}, ' \
                   f'"start": {{{members}}}}}'
        return body.encode()[:caps.MAX_PAYLOAD + 16]

    def extreme(self, kind: str) -> bytes:
        value = self.base(kind)
        nums = [p for p in json_paths(value) if isinstance(json_get(value, p), (int, float))
                and not isinstance(json_get(value, p), bool)]
        if kind == "plan" and self.r.random() < 0.5:
            value[self.r.choice(["velocity_scaling", "acceleration_scaling", "planning_time",
                                 "sample_rate", "seed"])] = 0.0
            nums = [p for p in json_paths(value) if isinstance(json_get(value, p), (int, float))
                    and not isinstance(json_get(value, p), bool)]
        if not nums:
            return _dumps(value)
        marker = "\u0001MARK\u0001"
        value = _set(value, self.r.choice(nums), marker)
        text = _dumps(value).decode()
        raw = self.r.choice(RAW_NUMBERS + [repr(float(self.r.choice(NUMBERS)))])
        return text.replace(json.dumps(marker), raw).encode()

    def wrong_types(self, kind: str) -> bytes:
        value = self.base(kind)
        paths = [p for p in json_paths(value) if p]
        if not paths:
            return _dumps(self.r.choice([[], "x", 1, None, [value]]))
        path = self.r.choice(paths)
        old = json_get(value, path)
        choices = [None, True, "1", [old], {"v": old}, 1, [], {}]
        return _dumps(_set(value, path, self.r.choice(choices)))

    def unicode_keys(self, kind: str) -> bytes:
        value = self.base(kind)
        dicts = [p for p in json_paths(value) if isinstance(json_get(value, p), dict)]
        target = json_get(value, self.r.choice(dicts))
        for _ in range(self.r.randint(1, 4)):
            target[self.unicode(self.r.randint(1, 40))] = self.scalar()
        return _dumps(value)

    def oversized(self, kind: str) -> bytes:
        return b'{"goal": {"named": "home"}, "planner": "' + b"x" * (caps.MAX_PAYLOAD + 1) + b'"}'


def _dumps(value: Any) -> bytes:
    return json.dumps(value, ensure_ascii=False).encode("utf-8", "surrogatepass")


def _set(value: Any, path: tuple[Any, ...], new: Any) -> Any:
    if not path:
        return new
    json_get(value, path[:-1])[path[-1]] = new
    return value


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
