"""Scene objects in a link's frame (issue 28 item 1): such an object moves with its link
(fk reports it where the link holds it), is checked against the scene and every link not
rigidly joined to its own, a plan keeps it out of a table (an independent FCL check at
0.002 rad), attach and detach keep where it is, and a file keeps its frame."""

from __future__ import annotations

import json

import numpy as np
import pytest

from arduinobot.client.replies import FkReply
from arduinobot.contract import wire
from arduinobot.contract.errors import InvalidRequest, StartInCollision
from arduinobot.scene.builder import SceneBuilder
from arduinobot.scene.change import restore
from arduinobot.scene.obstacles import rigid_links
from arduinobot.scene.state import SceneState
from arduinobot.service.plan.handlers import Handlers
from arduinobot.service.scene.file import SceneFile
from tests.helpers.carry import CarryCase
from tests.helpers.fk import link_pose
from tests.planner.planning.test_carried import _box_hits
from tests.service.test_scene_carry import applied


def _q(desc, values):
    return np.array([values.get(n, 0.0) for n in desc.robot.actuated_joints])


CAM = {"id": "cam", "shape": "box", "size": [0.05, 0.05, 0.05], "xyz": [0.0, 0.2, 0.3],
       "frame": "claw_support"}


def test_rigid_links_follow_fixed_joints_both_ways(desc):
    assert set(rigid_links(desc, "claw_support")) == {"claw_support", "horizontal_arm"}
    assert set(rigid_links(desc, "horizontal_arm")) == {"claw_support", "horizontal_arm"}
    assert set(rigid_links(desc, "gripper_left")) == {"gripper_left"}
    # the world anchor is joined to the base by the fixed virtual joint
    assert "base_link" in rigid_links(desc, "world")


def test_an_object_in_a_link_frame_moves_with_it(desc, scene_builder):
    s = applied(SceneState(), {"add": [CAM]}, scene_builder)
    # kept as sent (its frame too), planned as a massless object its link carries
    assert s.to_json()["objects"] == [CAM] and s.to_json()["attached"] == []
    assert s.snapshot.obstacles == ()
    (fixed,) = s.snapshot.attached
    assert fixed.link == "claw_support" and fixed.mass == 0.0
    assert set(fixed.touch_links) == {"claw_support", "horizontal_arm"}
    h = Handlers(desc)
    local = np.eye(4)
    local[:3, 3] = CAM["xyz"]
    for state in ({}, {"joint_1": 0.7, "joint_3": -0.4}):
        fk = h.handle("fk", wire.decode("fk", json.dumps({"joints": state})), scene=s.snapshot)
        link_t = link_pose(desc.robot, "claw_support", list(desc.robot.actuated_joints),
                           _q(desc, state))
        assert np.allclose(np.array(fk["carried"]["cam"]["matrix"]), link_t @ local,
                           atol=1e-9)
        # fixed to its link, not picked up: the reply and the client say which
        assert fk["carried"]["cam"]["fixed"] is True
        assert FkReply.parse({**fk, "request_id": "r"}).carried["cam"].fixed


def test_a_world_obstacle_in_its_way_is_a_contact_of_the_object_not_the_link(desc, scene_builder):
    s = applied(SceneState(), {"add": [CAM]}, scene_builder)
    h = Handlers(desc)
    state = {"joint_1": 0.5}
    link_t = link_pose(desc.robot, "claw_support", list(desc.robot.actuated_joints),
                       _q(desc, state))
    where = (link_t @ np.array([*CAM["xyz"], 1.0]))[:3]
    ball = {"id": "ball", "shape": "sphere", "radius": 0.01, "xyz": where.tolist()}
    check = h.handle("check", wire.decode("check", json.dumps(
        {"joints": state, "obstacles": [ball]})), scene=s.snapshot)
    assert not check["valid"]
    assert {tuple(sorted(p)) for p in check["pairs"]} == {("ball", "cam")}
    # where the link has moved it away, the ball is free
    free = h.handle("check", wire.decode("check", json.dumps(
        {"joints": {"joint_1": -0.5}, "obstacles": [ball]})), scene=s.snapshot)
    assert free["valid"]


def test_a_plan_keeps_an_object_fixed_in_the_link_frame_out_of_the_table(desc, scene_builder):
    case = CarryCase(desc, desc.tcp)  # a box hanging below the tool sweeps the table directly
    box = case.box
    obj = {"id": box.id, "shape": "box", "size": list(box.size), "xyz": list(box.xyz),
           "frame": case.link}
    # it hangs between the fingers: without them as touch links the start collides
    with pytest.raises(StartInCollision) as e:
        case.mp.solve(case.request(applied(SceneState(), {"add": [obj]}, scene_builder)
                                   .snapshot.attached))
    assert box.id in {n for p in e.value.pairs for n in p}
    obj["touch_links"] = ["gripper_left", "gripper_right"]
    s = applied(SceneState(), {"add": [obj]}, scene_builder)
    assert set(s.snapshot.attached[0].touch_links) == {case.link, "horizontal_arm",
                                                        "gripper_left", "gripper_right"}
    res = case.mp.solve(case.request(s.snapshot.attached))
    assert res.verification.ok
    assert np.allclose(res.trajectory.positions[-1][0], 0.8, atol=1e-3)
    assert _box_hits(desc, case.names, np.asarray(res.trajectory.positions), box, case.link,
                     case.table) == 0


def test_attach_and_detach_keep_it_where_its_link_holds_it(desc, scene_builder):
    s = applied(SceneState(), {"add": [CAM]}, scene_builder)
    state = {"joint_1": 0.3, "joint_2": 0.2}
    q = _q(desc, state)
    link_t = link_pose(desc.robot, "claw_support", list(desc.robot.actuated_joints), q)
    local = np.eye(4)
    local[:3, 3] = CAM["xyz"]
    world = link_t @ local
    s = applied(s, {"attach": [{"object": "cam", "link": "horizontal_arm", "mass": 0.05}],
                    "state": state}, scene_builder)
    (held,) = s.snapshot.attached
    assert held.link == "horizontal_arm" and held.mass == 0.05 and not s.objects
    arm_t = link_pose(desc.robot, "horizontal_arm", list(desc.robot.actuated_joints), q)
    assert np.allclose(arm_t @ held.shape.pose(), world, atol=1e-9)
    s = applied(s, {"detach": ["cam"], "state": state}, scene_builder)
    (put,) = s.objects
    assert put.link is None and "frame" not in put.data
    assert np.allclose(put.obstacle.pose(), world, atol=1e-9)


def test_the_file_keeps_the_frame(desc, scene_builder, tmp_path):
    s = applied(SceneState(), {"add": [CAM]}, scene_builder)
    f = SceneFile(tmp_path / "scene.json")
    f.save(s)
    back = restore(f.load(), scene_builder)
    assert back.to_json() == s.to_json()
    assert [a.shape_key() for a in back.snapshot.attached] == \
        [a.shape_key() for a in s.snapshot.attached]


@pytest.mark.parametrize("obj, field", [
    ({**CAM, "frame": "claw"}, "add[0].frame"),
    ({**CAM, "touch_links": ["claw"]}, "add[0].touch_links[0]"),
    ({**CAM, "frame": "world", "touch_links": ["claw_support"]}, "add[0].touch_links"),
])
def test_an_unknown_frame_or_touch_link_names_the_field(scene_builder, obj, field):
    with pytest.raises(InvalidRequest) as e:
        applied(SceneState(), {"add": [obj]}, scene_builder)
    assert e.value.field == field
    if field.endswith("frame"):
        assert "claw_support" in e.value.details["links"]


def test_without_a_robot_model_a_link_frame_is_refused(desc, tmp_path):
    bare = SceneBuilder(tuple(desc.robot.links), tmp_path / "m")
    with pytest.raises(InvalidRequest) as e:
        applied(SceneState(), {"add": [CAM]}, bare)
    assert e.value.field == "add[0].frame" and "no robot model" in e.value.message
