"""Issue 42 item 1 on a claw of one moving jaw (LeRobot's SO-101, as its folder is
published: tests/helpers/so101.py): the fixed jaw is the link the moving one turns on, and
its 5-joint arm points the claw down to take a cube resting on a table."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.tasks import plan_task, task_from_mapping
from tests.helpers.so101 import make_so101

CUBE = 0.025  # [m] a cube a hobby arm's demos pick up
TABLE_TOP = 0.05  # [m]
CUBE_XY = (0.2, 0.0)  # [m] in front of the base, well within reach


@pytest.fixture(scope="module")
def so101(tmp_path_factory):
    from arduinobot.planner.planning.pipeline import MotionPlanner
    return MotionPlanner(load_description(make_so101(tmp_path_factory.mktemp("so101"))))


def _task(**pick) -> dict:
    return {"obstacles": [
        {"id": "table", "shape": "box", "size": [0.2, 0.3, 0.02],
         "xyz": [0.25, 0.0, TABLE_TOP - 0.01]},
        {"id": "cube", "shape": "box", "size": [CUBE] * 3,
         "xyz": [CUBE_XY[0], CUBE_XY[1], TABLE_TOP + CUBE / 2]}],
        "steps": [{"pick": "cube", **pick}], "seed": 1}


def test_the_fixed_jaw_is_the_link_the_moving_one_turns_on(so101):
    from arduinobot.planner.tasks.pick import claw
    c = claw(so101)
    assert c.fingers == ("gripper_link", "moving_jaw_so101_v1_link")
    assert c.link == "gripper_frame_link"
    # the published tool frame points out of the claw along z, the moving jaw on its -x
    # side (config/tcp.yaml puts the tool point 1 cm in from the fixed jaw, at -x)
    assert c.along[2] > 0.95 and c.axis[0] < -0.95
    # closed, the tips nearly meet; open, they are centimetres apart
    assert 0.0 <= c.gaps.min() < 0.005 and 0.08 < c.opening < 0.15
    v = c.value_for(CUBE)
    assert np.interp(v, c.values, c.gaps) == pytest.approx(CUBE, abs=1e-6)


def test_the_so101_picks_a_resting_cube_from_above(so101):
    from arduinobot.planner.tasks.pick import claw
    result = plan_task(so101, task_from_mapping(_task()))
    assert [s.kind for s in result.steps] == ["gripper", "move", "line", "attach",
                                              "gripper", "line"]
    for s in result.steps:
        if s.result is not None:
            assert s.result.verification.ok and s.result.verification.certified, s.label
    (choice,) = result.choices
    assert choice.name.startswith("above") and choice.details["supports"] == ["table"]
    c = claw(so101)
    grip = result.steps[4]
    q = np.array([grip.end[n] for n in so101.joint_names])
    r = so101.world(()).kin.link_pose(q, c.link)[:3, :3]
    # the claw points down (within the aim's 15 degrees) and closes level
    assert np.degrees(np.arccos(-(r @ c.along)[2])) <= 15.0 + 1e-6
    # closed to the cube's width across the jaws there, not a fixed value
    gap = float(np.interp(grip.end["gripper"], c.values, c.gaps))
    assert gap == pytest.approx(choice.details["width"], abs=1e-3)
    assert CUBE - 1e-6 <= choice.details["width"] <= CUBE * np.sqrt(3)
    # the cube is carried from the attach to the end, the jaws its touch links
    assert [s.index for s in result.steps if s.carried == ("cube",)] == [3, 4, 5]
    attach = result.steps[3]
    assert attach.object == "cube" and set(c.fingers) <= set(attach.touch_links)


def test_a_cube_wider_than_the_jaws_open_is_refused_with_both_widths(so101):
    from arduinobot.planner.tasks import TaskStepFailed
    from arduinobot.planner.tasks.pick import claw
    body = _task()
    big = 0.14
    body["obstacles"][1].update(size=[big] * 3, xyz=[0.22, 0.0, TABLE_TOP + big / 2])
    with pytest.raises(TaskStepFailed) as e:
        plan_task(so101, task_from_mapping(body))
    err = e.value.details["error"]
    assert err["code"] == "OBJECT_TOO_WIDE", err
    assert err["details"]["width"] >= big - 1e-6
    assert err["details"]["opening"] == pytest.approx(claw(so101).opening, abs=1e-4)
