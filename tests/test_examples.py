"""Every script in examples/ runs as a user runs it: a fresh interpreter, the service's
endpoint as its argument (a real `arduinobot serve`, the shared ``server`` fixture)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.helpers.serve import REPO, Server

EXAMPLES = REPO / "examples"


def _run(script: str, *args: str, timeout: float = 240.0) -> str:
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
    r = subprocess.run([sys.executable, str(EXAMPLES / script), *args], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{script} exited {r.returncode}:\n{r.stdout}\n{r.stderr}"
    return r.stdout


def test_every_example_is_run_here() -> None:
    tested = {"01_plan.py", "02_own_robot.py", "03_scene.py", "04_execute_twin.py",
              "05_raw_zenoh.py"}
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


def test_01_plan(server: Server) -> None:
    out = _run("01_plan.py", server.endpoint)
    assert "reach_left: " in out and "certified True" in out
    assert "saved and read back: True" in out
    assert "GOAL_OUT_OF_REACH: " in out


def test_02_own_robot(tmp_path: Path) -> None:
    out = _run("02_own_robot.py", str(tmp_path))
    pkg = tmp_path / "my_arm_description"
    assert (pkg / "package.xml").is_file() and (pkg / "meshes" / "link.stl").is_file()
    assert "PASS  mesh" in out and "FAIL" not in out
    assert "my_arm: joints ['yaw', 'elbow']" in out
    assert "certified True" in out


def test_03_scene(server: Server) -> None:
    out = _run("03_scene.py", server.endpoint)
    # the ball forces a detour: more than the straight line's two waypoints
    around = next(ln for ln in out.splitlines() if ln.startswith("reach_left around a ball"))
    assert "(RRTConnect)" in around and " 2 waypoints" not in around
    assert "GOAL_IN_COLLISION: " in out and "/ball" in out


def test_04_execute_twin(server: Server) -> None:
    out = _run("04_execute_twin.py", server.endpoint)
    assert out.startswith("completed: ")
    assert "contacts: none" in out


def test_05_raw_zenoh(server: Server) -> None:
    out = _run("05_raw_zenoh.py", server.endpoint)
    assert "robot arduinobot: joints ['joint_1', 'joint_2', 'joint_3', 'joint_4']" in out
    assert "certified True" in out
    assert "INVALID_REQUEST: goal.named: no named state 'no_such_state'" in out
