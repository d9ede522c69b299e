"""A point cloud in the kept scene's model (arduinobot.scene.state): an apply keeps it as
cells at the robot's state it gives, a later add of the same id replaces it, plans go
around it (an independent FCL check, a box per kept cell, every 0.002 rad), and hostile
clouds are refused naming the field."""

from __future__ import annotations

import base64

import fcl
import numpy as np
import orjson
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import load_description
from arduinobot.planner.frames import RobotFrames
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.scene.builder import SceneBuilder
from arduinobot.scene.change import apply, restore
from arduinobot.scene.cloud import encode_points
from arduinobot.scene.state import SceneState
from arduinobot.service.scene.apply import decode_apply
from tests.planner.planning.test_carried import _dense

START = {"joint_1": -0.8}
END = {"joint_1": 0.8}


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    d = load_description()
    mp = MotionPlanner(d)
    base = mp.context.world(())
    frames = RobotFrames(d, kin=base.kin, bodies=base.bodies)
    builder = SceneBuilder(tuple(d.robot.links), tmp_path_factory.mktemp("meshes"),
                           robot=frames)
    return d, mp, base, builder


def _on_the_robot(base, q: np.ndarray) -> np.ndarray:
    poses = base.kin.link_poses(q)
    return np.vstack([p[::7] @ poses[f][:3, :3].T + poses[f][:3, 3]
                      for f, (_, p) in zip(base.bodies.frames, base.bodies.points)])


def _table_and_pillar(base, q: np.ndarray) -> tuple[np.ndarray, int]:
    """A floor around the arm (noisy), a pillar in joint 1's swing, points on the arm
    itself at ``q``, and every 500th point NaN: the points and how many are NaN."""
    rng = np.random.default_rng(7)
    n, m = 20_000, 8_000
    floor = np.column_stack([rng.uniform(-1.2, 1.2, n), rng.uniform(-1.2, 1.2, n),
                             rng.normal(0.0, 0.003, n)])
    pillar = np.column_stack([rng.uniform(-0.05, 0.05, m), rng.uniform(0.9, 1.0, m),
                              rng.uniform(0.0, 1.6, m)])
    pts = np.vstack([floor, pillar, _on_the_robot(base, q)])
    pts[::500] = np.nan
    return pts, len(pts[::500])


def _cloud(points, **extra) -> dict:
    return {"id": "camera", "shape": "points", "points": encode_points(points),
            "resolution": 0.02, **extra}


def _hits(base, clouds, qs: np.ndarray) -> int:
    """FCL: the robot's meshes at each state against one box per kept cell."""
    manager = fcl.DynamicAABBTreeCollisionManager()
    boxes = []
    for c in clouds:
        r = c.cells.resolution
        for center in c.cells.centers:
            boxes.append(fcl.CollisionObject(fcl.Box(r, r, r), fcl.Transform(center)))
    manager.registerObjects(boxes)
    manager.setup()
    links = [fcl.CollisionObject(g, fcl.Transform()) for g in base.bodies.geometries]
    hits = 0
    for q in qs:
        poses = base.kin.link_poses(q)
        for obj, frame in zip(links, base.bodies.frames):
            t = poses[frame]
            obj.setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
            data = fcl.CollisionData(request=fcl.CollisionRequest())
            manager.collide(obj, data, fcl.defaultCollisionCallback)
            hits += data.result.is_collision
    return hits


def test_a_cloud_is_kept_filtered_and_planned_around(robot):
    d, mp, base, builder = robot
    q0 = np.array([-0.8, 0.0, 0.0, 0.0])
    pts, nans = _table_and_pillar(base, q0)
    s = apply(SceneState(), {"add": [_cloud(pts)], "state": START}, builder)
    (cloud,) = s.clouds
    c = cloud.counts
    assert c["dropped"] == nans and c["points"] == len(pts)
    assert c["filtered_robot"] >= len(_on_the_robot(base, q0)) - nans
    assert c["kept"] + c["dropped"] + c["filtered_robot"] + c["filtered_objects"] == len(pts)
    assert s.snapshot.assumptions() == {"camera": "free"} and s.ids() == ("camera",)
    assert cloud.data["state"] == START  # kept as taken: a restore keeps it the same way

    # the direct swing crosses the pillar; the plan does not touch a cell (FCL)
    direct = np.array([[q1, 0.0, 0.0, 0.0] for q1 in np.linspace(-0.8, 0.8, 161)])
    assert _hits(base, s.snapshot.clouds, direct) > 0
    res = mp.solve(MotionRequest(goal=JointGoal(END), start=START, seed=3,
                                 planning_time=5.0, clouds=s.snapshot.clouds))
    qs = _dense(np.asarray(res.trajectory.positions, float))
    assert np.allclose(qs[-1], [0.8, 0, 0, 0], atol=1e-3)
    assert _hits(base, s.snapshot.clouds, qs) == 0

    # a restore (the scene file) keeps the same cells
    again = restore(orjson.loads(orjson.dumps(s.to_json())), builder)
    assert np.array_equal(again.clouds[0].bodies[0].cells.index, cloud.bodies[0].cells.index)


def test_a_later_add_of_the_same_id_replaces_the_cloud(robot):
    _, _, base, builder = robot
    wall = np.column_stack([np.full(500, -1.0), np.linspace(-1, 1, 500), np.full(500, 0.5)])
    s = apply(SceneState(), {"add": [_cloud(wall), {"id": "box", "shape": "box",
                                                     "size": [0.1, 0.1, 0.1],
                                                     "xyz": [1.0, 1.0, 0.05]}]}, builder)
    s2 = apply(s, {"add": [_cloud(wall + [0.0, 0.0, 0.3], unknown="free")]}, builder)
    assert s2.revision == s.revision + 1 and len(s2.clouds) == 1 and s2.ids() == ("box",
                                                                                  "camera")
    z = s2.snapshot.clouds[0].cells.centers[:, 2]
    assert np.all(np.abs(z - 0.81) < 0.02)
    # a cloud's id is not a box's: refused, and a box may not take a cloud's id
    for change, field in [({"add": [_cloud(wall, id="box")]}, "add[0].id"),
                          ({"add": [{"id": "camera", "shape": "sphere", "radius": 0.1}]},
                           "add[0].id")]:
        with pytest.raises(InvalidRequest) as e:
            apply(s2, change, builder)
        assert e.value.field == field
    s3 = apply(s2, {"remove": ["camera"]}, builder)
    assert s3.clouds == () and s3.snapshot.clouds == ()


def _raw(points: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.asarray(points, dtype).tobytes()).decode()


@pytest.mark.parametrize("points,field", [
    ({"format": "xyz32", "data": _raw(np.zeros((4, 3)), "<f4")[:-8]}, "add[0].points.data"),
    ({"format": "xyz32", "data": base64.b64encode(b"\0" * 13).decode()},
     "add[0].points.data"),
    ({"format": "xyz32", "data": _raw(np.full((9, 3), np.nan), "<f4")}, "add[0].points"),
    ({"format": "xyz32", "data": "not base64!"}, "add[0].points.data"),
])
def test_hostile_clouds_are_refused_naming_the_field(robot, points, field):
    builder = robot[3]
    change = {"add": [{**_cloud(np.zeros((1, 3))), "points": points}], "state": {}}
    with pytest.raises(InvalidRequest) as e:
        apply(SceneState(), change, builder)
    assert e.value.field == field


def test_a_frame_that_is_no_link_and_too_many_points_are_refused(robot):
    builder = robot[3]
    with pytest.raises(InvalidRequest) as e:
        apply(SceneState(), {"add": [_cloud(np.ones((3, 3)), frame="camera_link")]},
              builder)
    assert e.value.field == "add[0].frame"
    many = {"format": "xyz32", "data": base64.b64encode(bytes(12 * 2_000_001)).decode()}
    with pytest.raises(InvalidRequest) as e:
        apply(SceneState(), {"add": [{**_cloud(np.ones((1, 3))), "points": many}]}, builder)
    assert e.value.field == "add[0].points.data" and e.value.details["limit"] == 2_000_000


def test_the_schema_takes_a_cloud_and_refuses_a_wrong_format():
    ok = decode_apply(orjson.dumps({"add": [_cloud(np.ones((2, 3)), unknown="free")]}))
    assert ok["add"][0]["shape"] == "points"
    for obj, field in [({**_cloud(np.ones((2, 3))), "points": {"format": "xyzrgb",
                                                                 "data": "AAAA"}},
                        "add[0].points.format"),
                       ({"id": "b", "shape": "box", "size": [1, 1, 1], "resolution": 0.01},
                        "add[0]")]:
        with pytest.raises(InvalidRequest) as e:
            decode_apply(orjson.dumps({"add": [obj]}))
        assert e.value.details["field"].startswith(field), e.value


def test_a_task_in_the_kept_scene_goes_around_its_cloud(robot):
    from dataclasses import replace

    from arduinobot.planner.tasks import plan_task, task_from_mapping

    _, mp, base, builder = robot
    q0 = np.array([-0.8, 0.0, 0.0, 0.0])
    pts, _ = _table_and_pillar(base, q0)
    s = apply(SceneState(), {"add": [_cloud(pts)], "state": START}, builder)
    task = task_from_mapping({"start": START, "seed": 5, "planning_time": 5.0,
                              "steps": [{"move": {"joints": END}}]})
    result = plan_task(mp, replace(task, clouds=s.snapshot.clouds))
    qs = _dense(result.samples()[1])
    assert np.allclose(qs[-1], [0.8, 0, 0, 0], atol=1e-3)
    assert _hits(base, s.snapshot.clouds, qs) == 0
