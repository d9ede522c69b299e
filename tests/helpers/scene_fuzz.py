"""Hostile scene inputs, seeded: mutations of apply requests (attach and detach too) and
junk mesh bytes (for tests/service/test_scene_store.py, tests/service/test_scene_carry.py and
bench/scene.py)."""

from __future__ import annotations

import base64
import random
import struct
from typing import Any

import numpy as np
import trimesh


def b64(data: bytes) -> str:
    return base64.b64encode(data).decode()


def binary_stl(triangles: np.ndarray, count: int | None = None) -> bytes:
    """A binary STL of ``triangles`` (shape (n, 3, 3)), its header claiming ``count``."""
    head = b"\0" * 80 + struct.pack("<I", len(triangles) if count is None else count)
    body = b"".join(struct.pack("<12fH", 0, 0, 0, *t.ravel(), 0) for t in triangles)
    return head + body


def junk_mesh(r: random.Random) -> str:
    """Base64 of bytes that are almost, or not at all, a mesh."""
    kind = r.randrange(5)
    if kind == 0:  # random bytes
        raw = bytes(r.getrandbits(8) for _ in range(r.randrange(0, 300)))
    elif kind == 1:  # a binary STL cut short
        raw = trimesh.creation.box().export(file_type="stl")[:r.randrange(0, 700)]
    elif kind == 2:  # OBJ with indices out of range, negative, or non-numbers
        raw = r.choice([b"v 0 0 0\nf 1 2 99\n", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -5 2 3\n",
                        b"v nan 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n",
                        b"v a b c\nf x y z\n", b"f 1 2 3\n" * 50])
    elif kind == 3:
        raw = b"solid x\n" + bytes(r.getrandbits(8) for _ in range(200))
    else:  # a header claiming none, more, or 2^31 triangles
        raw = binary_stl(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32),
                         r.choice([0, 2, 2**31]))
    return b64(raw)


def carry_seeds(link: str = "claw_support") -> list[dict[str, Any]]:
    """Valid-looking applies with attach, detach and state, for :func:`mutate` (``keep``:
    a scene object, ``held``: one the seeds attach; a real scene may hold neither)."""
    box = {"id": "held", "shape": "box", "size": [0.02, 0.02, 0.05], "xyz": [0, 0, -0.05]}
    return [
        {"attach": [{"object": "keep", "link": link, "mass": 0.2, "com": [0, 0, 0.01]}],
         "state": {"joint_1": 0.3}},
        {"attach": [{"object": {**box, "frame": link}, "link": link,
                     "touch_links": [link, "gripper_left"]}], "if_revision": 1},
        {"detach": ["held"], "state": {"joint_1": -0.2, "joint_2": 0.1}},
        {"add": [{**box, "id": "new", "xyz": [3, 3, 3]}], "attach": [
            {"object": "new", "link": link}], "detach": ["held"], "remove": ["keep"]},
    ]


def mutate(r: random.Random, value: Any) -> Any:
    """One random change somewhere in a JSON value."""
    if isinstance(value, dict) and value and r.random() < 0.8:
        k = r.choice(sorted(value))
        return {**value, k: mutate(r, value[k])} if r.random() < 0.7 else \
            {kk: v for kk, v in value.items() if kk != k}
    if isinstance(value, list) and value and r.random() < 0.8:
        i = r.randrange(len(value))
        return [*value[:i], mutate(r, value[i]), *value[i + 1:]]
    return r.choice([None, True, -1, 0, 1e308, -1e-320, 2**63, "", "x" * 70, "world",
                     "claw_support", [], {}, [1, 2, 3], [0.0] * 3, {"format": "obj"},
                     "mesh", "box", [1e9, 0, 0], junk_mesh(r), {"a": {"b": [[[]]]}},
                     "joint_1", {"joint_1": 99}, {"nope": 0}, {"gripper_left_joint": 0.1},
                     "held", "keep", "base_link", ["held", "held"], -0.0, 1e-300])
