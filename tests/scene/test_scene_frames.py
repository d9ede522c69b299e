"""src/arduinobot/scene/frames.py: one attach and detach for the kept scene and for tasks,
with one contact rule: a task's attach refuses an object that already touches a link of
the robot that is not among its touch links, as the kept scene's does."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.frames import RobotFrames
from arduinobot.planner.tasks import TaskStepFailed, plan_task, task_from_mapping
from arduinobot.scene.frames import attach, detach
from arduinobot.scene.obstacles import Obstacle


@pytest.fixture(scope="module")
def robot():
    from arduinobot.planner.planning.pipeline import MotionPlanner

    d = load_description()
    return d, MotionPlanner(d), RobotFrames(d)


def test_attach_then_detach_puts_the_object_back_where_it_was(robot):
    d, _, frames = robot
    q = frames.state({"joint_1": 0.4}, field="state")
    link = d.tcp.parent_link
    far = Obstacle("far", "box", size=(0.02, 0.03, 0.04), xyz=(0.3, -0.2, 2.5),
                   rpy=(0.1, 1.2, -0.3))
    # the frames' round trip, not a grasp: the object 2 m off, which a pick's reach refuses
    held = attach(frames, far, link, q, where="attach[0]", reach=3.0)
    assert held.link == link and held.touch_links  # the gripper's by default
    back = detach(frames, held, q)
    assert np.allclose(back.pose(), far.pose(), atol=1e-12) and back.geometry == far.geometry


def test_a_task_s_attach_refuses_an_object_touching_the_arm(robot):
    d, planner, frames = robot
    at = frames.link_pose(frames.state(None, field="state"), "horizontal_arm")[:3, 3]
    task = task_from_mapping({
        "obstacles": [{"id": "ball", "shape": "sphere", "radius": 0.05, "xyz": at.tolist()}],
        "steps": [{"attach": "ball", "link": d.tcp.parent_link}]})
    with pytest.raises(TaskStepFailed) as e:
        plan_task(planner, task)
    assert e.value.index == 0 and e.value.error.field == "steps[0].attach"
    assert ["ball", "horizontal_arm"] in e.value.error.details["pairs"]
