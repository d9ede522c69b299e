"""Issue 42: `arduinobot task` with a pick and a place by name, on the MuJoCo twin: the
output says which grasp and which spot were chosen and how many were tried, and where
the box ended."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tests.helpers.cli import run_cli
from tests.helpers.pick_place import BOX, TABLE_TOP, pick_and_place_by_name

pytestmark = pytest.mark.slow


def test_task_sim_says_which_candidate_it_chose_and_where_the_box_ended(course_ws,
                                                                        tmp_path: Path):
    f = tmp_path / "two_steps.json"
    f.write_text(json.dumps(pick_and_place_by_name()))
    report = tmp_path / "report.json"
    out = run_cli("task", str(f), str(course_ws.xacro), "--sim", "--fast", "--report",
                  str(report), "--package-dir", str(course_ws.src), "--moveit-config",
                  str(course_ws.moveit_pkg), timeout=900)
    assert out.returncode == 0, out.stdout + out.stderr
    assert re.search(r"step 0 pick box: chose .+ \(tried \d+ of \d+\)", out.stdout), out.stdout
    assert "step 1 place box: chose position (tried 1 of 1)" in out.stdout, out.stdout
    rep = json.loads(report.read_text())
    place = rep["planned"]["choices"][1]["details"]["position"]
    floor = next(o for o in rep["planned"]["obstacles"] if o["id"] == "bin_floor")
    want = [place[0], place[1], floor["xyz"][2] + floor["size"][2] / 2 + BOX / 2]
    assert place[2] == pytest.approx(TABLE_TOP + 0.01 + BOX / 2, abs=1e-3)
    ended = rep["execution"]["objects"]["box"]
    assert np.linalg.norm(np.subtract(ended, want)) < 0.01, (ended, want)
