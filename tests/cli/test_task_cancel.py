"""Ctrl-C during ``arduinobot task FILE --sim`` (issue 38, item 8): the arm stops smoothly
within its limits, off the path early (not by finishing the motion), and the command
exits 130 as ``execute`` does (before: it finished the whole motion and exited 1)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest

from tests.helpers.so101 import make_so101

#: a slow move to the SO-101's "ready" state from joint zero: seconds of motion
TASK = {"velocity_scaling": 0.1, "acceleration_scaling": 0.1,
        "steps": [{"move": {"named": "ready"}}]}


def test_ctrl_c_during_task_sim_stops_smoothly_and_exits_130(tmp_path):
    urdf = make_so101(tmp_path)
    (tmp_path / "slow.json").write_text(json.dumps(TASK))
    report = tmp_path / "out.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "arduinobot.cli.main", "task", str(tmp_path / "slow.json"), urdf.name,
         "--sim", "--report", str(report)],
        cwd=urdf.parent, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        seen = []
        for line in proc.stderr:  # the motion starts right after this line
            seen.append(line)
            if line.startswith("executing "):
                break
        else:
            raise AssertionError("never started executing: " + "".join(seen))
        duration = float(line.split()[1])
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, "".join(seen) + stderr
    ex = json.loads(report.read_text())["execution"]
    assert ex["outcome"] == "cancelled", ex
    assert ex["trajectory_duration"] == pytest.approx(duration, abs=1e-3)  # printed to 1 ms
    # stopped, not finished: at rest well before the motion would have ended
    assert ex["cancelled_at"] + ex["stop_time"] < duration, ex
    assert all(v <= 1 + 1e-6 for v in ex["peak_ratio"].values()), ex["peak_ratio"]
