"""MPlib 0.2.1, the peer with our stack (OMPL RRTConnect, FCL, TOPP-RA), in its own venv.

MPlib pins numpy 1.x, so it runs in ``.bench-venvs/mplib`` (created on first use) through
bench/_lib/mplib_runner.py, JSON in and out; its trajectories are rebuilt here from its
toppra data for our verifier and the independent re-check. (Not named ``mplib.py``: the
runner, started as a script from this folder, would import it instead of MPlib.)
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[2]
VENV = REPO / ".bench-venvs" / "mplib"
RUNNER = Path(__file__).with_name("mplib_runner.py")


def mplib_python() -> Path:
    """The MPlib venv's python, creating the venv and installing mplib on first use."""
    py = VENV / "bin" / "python"
    if not py.exists():
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    if subprocess.run([str(py), "-c", "import mplib"], capture_output=True).returncode:
        subprocess.run([str(py), "-m", "pip", "install", "-q", "mplib==0.2.1"], check=True)
    return py


def run_mplib(spec: dict[str, Any], *, py: Path | None = None) -> dict[str, Any]:
    """Run bench/_lib/mplib_runner.py on ``spec`` (its input format) with ``py`` (default:
    :func:`mplib_python`); its output."""
    py = mplib_python() if py is None else py
    done = subprocess.run([str(py), str(RUNNER)], input=json.dumps(spec), text=True,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    if done.returncode:
        raise RuntimeError(f"mplib_runner failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(Path(spec["output"]).read_text())


class MplibTiming:
    """MPlib's trajectory, continuous: toppra's const-accel profile on its spline, j4 fixed."""

    def __init__(self, res: dict, dof: int, rest: np.ndarray) -> None:
        import toppra as ta
        from toppra.parametrizer import ParametrizeConstAccel
        path = np.array(res["path"])
        spline = ta.SplineInterpolator(np.linspace(0, 1, len(path)), path)
        self.traj = ParametrizeConstAccel(spline, np.array(res["gridpoints"]),
                                          np.array(res["sd"]))
        self.duration = float(self.traj.duration)
        self.dof, self.rest, self.n = dof, rest, path.shape[1]
        self.goal = self.evaluate(np.array([self.duration]))[0][0]

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ts = np.clip(np.atleast_1d(np.asarray(ts, float)), 0.0, self.duration)
        out = []
        for order in range(3):
            x = np.zeros((len(ts), self.dof)) if order else np.tile(self.rest, (len(ts), 1))
            x[:, :self.n] = self.traj(ts, order)
            out.append(x)
        return out[0], out[1], out[2]
