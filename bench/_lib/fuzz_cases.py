"""The fuzz benchmark's cases (bench/fuzz.py): the valid requests it mutates and
interleaves, and the generator of hostile ones."""

from __future__ import annotations

import json
import random
from collections.abc import Callable
from typing import Any

from arduinobot.contract import caps
from tests.helpers.json_paths import json_get, json_paths

KINDS = ("plan", "fk", "ik", "check")

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
