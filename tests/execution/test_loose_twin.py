"""What a task picks up, on the twin (issue 42): a loose object the task gives no mass
(a pick step's default) rests where it stands until the arm grips it. Before, MuJoCo made
it a 1 mg body whose contact with the table threw the SO-101's 2.5 cm cube 10 cm off its
spot in 0.3 s, before the arm came near it (``cube ends at 0.138 -0.016 0.051``)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.execution.robots.mjcf import LOOSE_DENSITY
from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
from arduinobot.scene.obstacles import AttachedObject, Obstacle
from tests.helpers.so101 import make_so101

EDGE = 0.025  # [m] the cube's edge
TABLE = Obstacle("table", "box", size=(0.2, 0.3, 0.02), xyz=(0.25, 0.0, 0.04))
CUBE_XYZ = (0.2, 0.0, 0.05 + EDGE / 2)  # resting on the table's top


@pytest.fixture(scope="module")
def desc(tmp_path_factory):
    return load_description(make_so101(tmp_path_factory.mktemp("so101")), env={})


@pytest.mark.parametrize("mass", [0.0, 0.02])
def test_a_cube_on_a_table_stays_where_it_stands(desc, mass):
    cube = AttachedObject(Obstacle("cube", "box", size=(EDGE,) * 3, xyz=CUBE_XYZ),
                          link="gripper_frame_link", mass=mass)
    robot = SimArduinobot(desc, obstacles=[TABLE], loose=[cube])
    try:
        m = robot.model
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "loose:cube")
        want = mass if mass > 0 else LOOSE_DENSITY * EDGE ** 3
        assert m.body_mass[b] == pytest.approx(want, rel=1e-9)
        for _ in range(200):  # 2 s
            robot.advance(0.01)
        pose = robot.object_pose("cube")
        assert np.linalg.norm(pose[:3, 3] - CUBE_XYZ) < 1e-3, pose[:3, 3]
        assert np.allclose(pose[:3, :3], np.eye(3), atol=1e-2), pose[:3, :3]
    finally:
        robot.close()
