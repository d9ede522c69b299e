"""The twin's floor (issue 38, item 5): an object let go with nothing under it lands on
the plane the base stands on (before: ``box ends at ... -29.840 m``), unless the ground
is opted out."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
from arduinobot.scene.obstacles import AttachedObject, Obstacle
from tests.helpers.so101 import make_so101

EDGE = 0.03  # [m] the cube's edge


@pytest.fixture(scope="module")
def desc(tmp_path_factory):
    return load_description(make_so101(tmp_path_factory.mktemp("so101")), env={})


def _dropped(desc, *, ground: bool) -> np.ndarray:
    """Where a cube let go 10 cm over the plane, beside the arm, is after 2 s [m]."""
    cube = AttachedObject(Obstacle("cube", "box", size=(EDGE,) * 3, xyz=(0.25, 0.15, 0.1)),
                          link="gripper_link", mass=0.02)
    robot = SimArduinobot(desc, loose=[cube], ground=ground)
    try:
        for _ in range(200):
            robot.advance(0.01)
        return robot.object_pose("cube")
    finally:
        robot.close()


def test_a_cube_let_go_lands_on_the_ground(desc):
    pose = _dropped(desc, ground=True)
    assert pose[2, 3] == pytest.approx(EDGE / 2, abs=2e-3), pose[:3, 3]
    assert np.allclose(pose[:2, 3], (0.25, 0.15), atol=5e-3), pose[:3, 3]


def test_without_the_ground_it_falls(desc):
    assert _dropped(desc, ground=False)[2, 3] < -1.0


def test_the_twin_takes_the_plans_ground(desc):
    """The execute service gives its twin the ground the plan or task had
    (``TwinScene.give``): a task planned with ``"ground": false`` runs on a twin without
    a floor, the next plan with the ground on one with it."""
    from arduinobot.service.execute.twin_scene import TwinScene

    cube = {"object": {"id": "cube", "shape": "box", "size": [EDGE] * 3,
                       "xyz": [0.25, 0.15, 0.1]}, "link": "gripper_link", "mass": 0.02}
    robot = SimArduinobot(desc)
    held = TwinScene()
    try:
        for ground, lands in ((False, False), (True, True)):
            held.give(robot, None, (), {"objects": [cube], "ground": ground})
            for _ in range(200):
                robot.advance(0.01)
            z = robot.object_pose("cube")[2, 3]
            assert (z == pytest.approx(EDGE / 2, abs=2e-3)) if lands else z < -1.0, z
        # a plan's own request: {"ground": false} takes the floor away (no task objects)
        held.give(robot, None, (), ground=False)
        assert "obstacle:ground" not in robot.xml
        held.give(robot, None, ())
        assert "obstacle:ground" in robot.xml
    finally:
        robot.close()
