"""Issue 29 item 5: the viewer plays a task: its steps on the scrubber, the carried box
moving with the gripper and left where the planner let it go, each line drawn."""

from __future__ import annotations

import socket

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.tasks import plan_task, task_from_mapping
from arduinobot.service.task.task_service import planned_body
from arduinobot.viewer.task_view import TaskPlayback
from tests.helpers.pick_place import pick_and_place


@pytest.fixture(scope="module")
def planned(course_ws):
    from arduinobot.planner.planning.pipeline import MotionPlanner
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src],
                         moveit_config=course_ws.moveit_pkg)
    result = plan_task(MotionPlanner(d), task_from_mapping(pick_and_place(), name="pick"))
    return d, result, planned_body(result, name="pick")


def test_a_task_reply_plays_with_its_steps_lines_and_carried_box(planned):
    d, result, body = planned
    kin = Kinematics(d.robot)
    play = TaskPlayback.from_reply(body, kin)
    assert play.trajectory.duration == pytest.approx(result.duration, abs=1e-9)
    assert [t for t, _ in play.marks] == pytest.approx(result.boundaries())
    assert play.marks[4][1] == "4 attach pick" and len(play.lines) == 4
    assert [c.object for c in play.carries] == ["box"]
    table_box = next(o for o in play.obstacles if o.id == "box").pose()
    attach_t, detach_t = play.carries[0].start, play.carries[0].end
    # before the attach the box is where the scene put it, also a step later
    assert np.allclose(play.object_pose("box", attach_t - 1e-3, kin), table_box)
    assert np.allclose(play.object_pose("box", attach_t, kin), table_box, atol=1e-9)
    # carried: after the LIN up (step 5) the box is 5 cm higher, give or take the tool's
    # turn over the line (a 3-joint arm cannot hold its orientation)
    up_end = body["steps"][6]["start_time"]
    lifted = play.object_pose("box", up_end, kin)
    assert lifted[2, 3] - table_box[2, 3] == pytest.approx(0.05, abs=0.01)
    # let go: where the planner put it back into the scene, and there it stays
    placed = next(o for o in result.obstacles if o.id == "box").pose()
    assert np.allclose(play.object_pose("box", detach_t, kin), placed, atol=1e-6)
    assert np.allclose(play.object_pose("box", play.trajectory.duration, kin), placed,
                       atol=1e-6)
    assert not np.allclose(placed[:3, 3], table_box[:3, 3], atol=0.1)


def test_a_reply_without_plans_is_refused_naming_the_step(planned):
    from arduinobot.execution.segments import InvalidTrajectory
    d, result, _ = planned
    bare = planned_body(result, name="pick", trajectories=False)
    with pytest.raises(InvalidTrajectory, match="step 0 has no plan"):
        TaskPlayback.from_reply(bare, Kinematics(d.robot))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_page_moves_the_carried_box_with_the_scrubber(planned):
    from arduinobot.viewer.app import RobotViewer
    from arduinobot.viewer.playback import PlaybackPanel
    from arduinobot.viewer.task_view import show_task

    d, _, body = planned
    viewer = RobotViewer(d, obstacles=TaskPlayback.from_reply(body, Kinematics(d.robot))
                         .obstacles, port=_free_port())
    try:
        playback = PlaybackPanel(viewer)
        play = TaskPlayback.from_reply(body, viewer.kin)
        show_task(viewer, playback, play)
        assert "4 attach pick" in playback._info.content
        assert playback._scrub.max == pytest.approx(play.trajectory.duration)
        handle = viewer._obstacle_handles["box"]
        for t in (0.0, body["steps"][6]["start_time"] + 0.5, play.trajectory.duration):
            playback._scrub.value = t  # what dragging the scrubber does
            want = play.object_pose("box", t, viewer.kin)
            assert np.allclose(handle.position, want[:3, 3], atol=1e-5), t
        playback.close()
    finally:
        viewer.close()
