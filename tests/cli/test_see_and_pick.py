"""See and pick, closed loop on the twin (issue 41): `arduinobot task see_and_pick.yaml
--sim` renders the course's base camera, finds the box through its marker, plans the pick
and place against the box as seen (padded), and the twin, its box a free body where it
really is, ends it in the bin within 1 cm of where the plan lets it go."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import yaml

pytest.importorskip("cv2")
pytest.importorskip("mujoco")

from tests.helpers import pick_place as pp  # noqa: E402
from tests.helpers.serve import REPO  # noqa: E402

pytestmark = pytest.mark.slow

TABLE_TOP = 0.25  # [m] lower than pick_place's: the box's marker in the camera's view
BOX = pp.BOX
MARKER = 0.065  # [m]: its label (10 % white around it) fits the box's 8 cm face
# on the circle of pick_place's box (as far from joint_1), turned towards the camera
R, BEARING = math.hypot(*pp.BOX_XY), math.radians(30.0)
TRUTH = (R * math.cos(BEARING), R * math.sin(BEARING), TABLE_TOP + pp.HOVER + BOX / 2)
BIN = pp.BIN_XY
TABLE_SHIFT = 0.2  # [m] the table's centre beyond the box's, away from the camera


def see_and_pick() -> dict:
    """pick_place's task with a lower table and a `see` section: the box is not in the
    task's scene, the camera finds it."""
    old = pp.TABLE_TOP
    pp.TABLE_TOP = TABLE_TOP  # the helper reads it at call time
    try:
        body = pp.pick_and_place(TRUTH[:2], BIN, seed=2)
    finally:
        pp.TABLE_TOP = old
    body["obstacles"] = [o for o in body["obstacles"] if o["id"] != "box"]
    # the box at the table's front edge: centred under it, the table top hides the
    # marker from a camera 3.5 cm above the floor (the twin draws the table)
    table = next(o for o in body["obstacles"] if o["id"] == "table")
    table["xyz"] = [TRUTH[0] + TABLE_SHIFT, TRUTH[1], table["xyz"][2]]
    body["see"] = {
        "camera": "rgb_camera_link",
        "markers": {"dictionary": "4x4_50", "size": MARKER, "objects": {3: {
            "id": "box", "shape": "box", "size": [BOX] * 3,
            "offset": {"xyz": [-BOX / 2, 0, 0], "rpy": [math.pi / 2, 0, -math.pi / 2]}}}},
        "twin": {"box": {"xyz": list(TRUTH), "rpy": [0, 0, 0]}},
    }
    return body


def test_see_and_pick_ends_the_box_in_the_bin(course_ws, tmp_path):
    task = tmp_path / "see_and_pick.yaml"
    task.write_text(yaml.safe_dump(see_and_pick(), sort_keys=False))
    report = tmp_path / "report.json"
    out = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "task", str(task),
                          str(course_ws.xacro), "--sim", "--fast", "--report", str(report),
                          "--package-dir", str(course_ws.src),
                          "--moveit-config", str(course_ws.moveit_pkg)],
                         cwd=REPO, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "saw box (marker 3)" in out.stdout
    rep = json.loads(report.read_text())
    (seen,) = rep["execution"]["seen"]
    assert np.linalg.norm(np.subtract(seen["xyz"], TRUTH)) < 0.005
    # the box is planned where it was seen, at its own size: the task picks it up (a
    # padded box would sink into its table, 2 mm below it)
    planned_box = next(o for o in rep["planned"]["obstacles"] if o["id"] == "box")
    np.testing.assert_allclose(planned_box["xyz"], seen["xyz"])
    assert planned_box["size"][0] == pytest.approx(BOX)
    assert rep["execution"]["outcome"] == "completed"
    # where the plan let the box go (forward kinematics of the reply), dropped onto the
    # bin's floor; the twin's box (gripped where it really was) ends within 1 cm of it
    from arduinobot.description import load_description
    from arduinobot.planner.kinematics.chain import Kinematics
    from arduinobot.viewer.task_view import TaskPlayback
    course = load_description(course_ws.xacro, package_dirs=[course_ws.src],
                              moveit_config=course_ws.moveit_pkg)
    kin = Kinematics(course.robot)
    planned = rep["planned"]
    end = TaskPlayback.from_reply(planned, kin).object_pose("box", planned["duration"], kin)
    floor = next(o for o in planned["obstacles"] if o["id"] == "bin_floor")
    place = [end[0, 3], end[1, 3], floor["xyz"][2] + floor["size"][2] / 2 + BOX / 2]
    sim = rep["execution"]["objects"]["box"]
    assert np.linalg.norm(np.subtract(sim, place)) < 0.01, (sim, place)
