"""HPP (hpp-python, from PyPI: ~1.2 GB of cmeel wheels) in its own venv, the certifying peer.

``.bench-venvs/hpp`` is created on first use (``pip install hpp-python``); its libraries
live under the venv's ``cmeel.prefix/lib``, which must be on ``LD_LIBRARY_PATH`` for
``import pyhpp.core``. bench/_lib/hpp_runner.py runs there, JSON in and out.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
VENV = REPO / ".bench-venvs" / "hpp"
RUNNER = Path(__file__).with_name("hpp_runner.py")


def hpp_env() -> dict[str, str]:
    """The environment HPP's python needs: the cmeel prefix's libraries found."""
    site = next((VENV / "lib").glob("python3*/site-packages"), None)
    if site is None:
        raise RuntimeError(f"{VENV}: no site-packages (is the venv created?)")
    prefix = site / "cmeel.prefix" / "lib"
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = os.pathsep.join(
        p for p in (str(prefix), env.get("LD_LIBRARY_PATH", "")) if p)
    env.pop("PYTHONPATH", None)  # our numpy 2 / pinocchio must not shadow the venv's
    return env


def hpp_python() -> Path:
    """The HPP venv's python, creating the venv and installing hpp-python on first use."""
    py = VENV / "bin" / "python"
    if not py.exists():
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    probe = [str(py), "-c", "import pyhpp.core"]
    if not (VENV / "lib").exists() or subprocess.run(probe, capture_output=True,
                                                     env=hpp_env()).returncode:
        subprocess.run([str(py), "-m", "pip", "install", "-q", "hpp-python"], check=True)
    return py


def run_hpp(s: Any, folder: Path, args: argparse.Namespace) -> dict[str, list[dict]]:
    """Every problem of setup ``s`` (bench/_lib/peer_mbm.py) ``args.repeat`` times; per
    problem name, HPP's results (bench/_lib/hpp_runner.py's output)."""
    from .scenes import obstacle_dicts
    spec = {"urdf": str(s.urdf), "srdf": str(s.srdf), "joints": list(s.joints),
            "validation": args.hpp_validation, "tolerance": args.hpp_tolerance,
            "optimise": True, "output": str(folder / "hpp-out.json"),
            "problems": {p.name: {"obstacles": obstacle_dicts(list(p.obstacles)),
                                  "runs": [{"start": list(p.start), "goal": list(p.goal),
                                            "planning_time": args.planning_time}]
                                  * args.repeat}
                         for p in s.problems}}
    py = hpp_python()
    done = subprocess.run([str(py), str(RUNNER)], input=json.dumps(spec), text=True,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=hpp_env())
    if done.returncode:
        raise RuntimeError(f"hpp_runner failed ({done.returncode}):\n{done.stderr[-3000:]}")
    out = json.loads(Path(spec["output"]).read_text())
    res: dict[str, list[dict]] = out["problems"]
    return res
