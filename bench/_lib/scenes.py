"""The benchmark scenes, their seeded problems, and the model files peers are given.

``SCENES`` and ``problems`` are the planning benchmark's (same names, same draws).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from arduinobot.description import load_description
from arduinobot.description.loader import read_model_text
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.obstacles import Obstacle

SCENES = {
    "self": [],
    "table": [Obstacle("table", "box", size=(0.6, 1.2, 0.05), xyz=(0, 1.0, 0.6))],
    "pillars": [Obstacle("p1", "box", size=(0.12, 0.12, 2.0), xyz=(0.5, 0.8, 1.0)),
                Obstacle("p2", "box", size=(0.12, 0.12, 2.0), xyz=(-0.5, 0.8, 1.0)),
                Obstacle("beam", "box", size=(1.2, 0.12, 0.12), xyz=(0, 0.8, 2.0))],
}


def problems(w: CollisionWorld, n: int, rng: np.random.Generator, *,
             gripper: bool = False) -> list[tuple]:
    """``n`` (start, goal, needs_detour) with valid ends, at least half needing a detour.
    The gripper (the joints after the arm's three) stays closed, or with ``gripper`` is
    drawn across its range too (arm and gripper moving together)."""
    lim = w.description.robot.position_limits(w.kin.joint_names)
    out, blocked = [], 0
    while len(out) < n:
        a = rng.uniform(lim[:, 0], lim[:, 1])
        b = rng.uniform(lim[:, 0], lim[:, 1])
        if not gripper:
            a[3:] = b[3:] = 0  # the gripper stays closed
        if not (w.is_valid(a) and w.is_valid(b)):
            continue
        is_blocked = w.first_invalid(interpolate(np.array([a, b]), 0.002)) >= 0
        if not is_blocked and blocked < len(out) / 2 + 1 and len(out) > 0:
            continue  # keep at least half needing a detour
        blocked += is_blocked
        out.append((a, b, is_blocked))
    return out


def obstacle_dicts(obstacles: list[Obstacle]) -> list[dict]:
    """Plain JSON-able obstacles (box/sphere/cylinder, world pose) for peers and re-checks."""
    out = []
    for o in obstacles:
        d = {"id": o.id, "shape": o.shape, "xyz": list(o.xyz), "rpy": list(o.rpy)}
        if o.shape == "box":
            d["size"] = list(o.size)
        elif o.shape == "sphere":
            d["radius"] = o.radius
        elif o.shape == "cylinder":
            d["radius"], d["length"] = o.radius, o.length
        else:
            raise ValueError(f"obstacle shape {o.shape!r} has no plain form")
        out.append(d)
    return out


def write_model(folder: Path) -> tuple[Path, Path]:
    """Our expanded URDF and SRDF in ``folder``; their paths.

    Mesh URIs become ``meshes/<file>`` next to the URDF (a symlink to our meshes folder):
    MPlib resolves every mesh path relative to the URDF's folder, absolute ones too, and
    yourdfpy does the same for relative ones.
    """
    d = load_description()
    text, _ = read_model_text(packages=d.packages)
    meshes = (d.package_root / "meshes").resolve()

    text = re.sub(r'filename="package://[^"]*/meshes/([^"]+)"', r'filename="meshes/\1"', text)
    if "package://" in text:
        raise ValueError("a package:// URI outside meshes/ is left in the URDF")
    folder.mkdir(parents=True, exist_ok=True)
    link = folder / "meshes"
    if link.is_symlink() or link.exists():
        link.unlink()
    link.symlink_to(meshes, target_is_directory=True)
    urdf, srdf = folder / "arduinobot.urdf", folder / "arduinobot.srdf"
    urdf.write_text(text)
    srdf.write_text(d.config.srdf.read_text())  # type: ignore[union-attr]
    return urdf, srdf
