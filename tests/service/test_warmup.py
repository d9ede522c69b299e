"""``python -m arduinobot.service.process.warmup`` (what ``./dev`` runs at set-up): the kernels compiled, and
the shipped robot's geometry in the artifact cache ``serve`` reads by default, so a first
``serve`` reads its part hulls instead of building them."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from arduinobot.description import load_description
from arduinobot.planner.collision.bodies import RobotBodies
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.service.process.disk_cache import DiskCache

ROOT = Path(__file__).resolve().parents[2]


def test_warmup_fills_the_default_cache_with_the_shipped_robots_geometry(tmp_path):
    env = {**os.environ, "ARDUINOBOT_CACHE": str(tmp_path)}
    done = subprocess.run([sys.executable, "-m", "arduinobot.service.process.warmup"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "geometry" in done.stderr
    for kind in ("obb-tree", "convex-hull", "part-hulls"):
        assert any((tmp_path / kind).glob("*.npz")), kind

    class Counting(DiskCache):
        def __init__(self, root: Path) -> None:
            super().__init__(root)
            self.stored: list[str] = []

        def store(self, kind, key, arrays):
            self.stored.append(kind)
            super().store(kind, key, arrays)

    cache = Counting(tmp_path)  # what serve reads: everything there, nothing built again
    d = load_description()
    RobotBodies.build(d, Kinematics(d.robot), cache=cache)
    assert cache.stored == []
