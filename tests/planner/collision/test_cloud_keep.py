"""A cloud request made ready to plan against (arduinobot.planner.collision.cloud_keep):
posed in its frame, self-filtered at the state it was taken, its unknown space stated."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import load_description
from arduinobot.planner.collision.cloud_keep import keep_cloud
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.cloud import encode_points
from arduinobot.scene.cloud_spec import CloudSpec
from arduinobot.scene.obstacles import Obstacle

STATE = np.array([0.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def world():
    return CollisionWorld(load_description())


def _spec(world, points, **extra):
    data = {"id": "cam", "shape": "points", "points": encode_points(points, "xyz64"),
            "resolution": 0.02, **extra}
    return CloudSpec.from_mapping(data, link_names=world.kin.link_names, where="add[0]")


def test_a_cloud_in_a_link_frame_lands_where_the_link_is(world):
    # a 10 cm cube of points 1 m ahead of base_plate, which turns with joint_1
    rng = np.random.default_rng(3)
    cube = rng.uniform(-0.05, 0.05, (3000, 3)) + [1.0, 0.0, 0.0]
    state = np.array([np.pi / 2, 0.0, 0.0, 0.0])
    kept = keep_cloud(world, _spec(world, cube, frame="base_plate"), state)
    plate = world.kin.link_poses(state)[world.kin.link_index["base_plate"]]
    expect = cube @ plate[:3, :3].T + plate[:3, 3]
    centers = kept.bodies[0].cells.centers
    assert np.abs(centers.mean(axis=0) - expect.mean(axis=0)).max() < 0.01
    assert kept.counts.kept == 3000 and kept.unknown == "free" and len(kept.bodies) == 1
    assert kept.reply()["filtered_robot"] == 0


def test_points_on_the_robot_and_on_known_objects_are_filtered(world):
    poses = world.kin.link_poses(STATE)
    on_arm = np.vstack([p @ poses[f][:3, :3].T + poses[f][:3, 3]
                        for f, (_, p) in zip(world.bodies.frames, world.bodies.points)])
    box = Obstacle("crate", "box", size=(0.2, 0.2, 0.2), xyz=(1.0, 1.0, 0.1))
    rng = np.random.default_rng(4)
    crate = rng.uniform(-0.1, 0.1, (500, 3)) + [1.0, 1.0, 0.1]
    wall = np.column_stack([np.full(2000, -1.0), rng.uniform(-1, 1, 2000),
                            rng.uniform(0, 1, 2000)])
    kept = keep_cloud(world, _spec(world, np.vstack([on_arm, crate, wall])), STATE,
                      objects=[box])
    c = kept.counts
    assert (c.robot, c.objects, c.kept) == (len(on_arm), 500, 2000)
    w = world.with_scene(clouds=kept.bodies)
    assert w.is_valid(STATE)


def test_nothing_left_is_refused_naming_the_points(world):
    poses = world.kin.link_poses(STATE)
    f, (_, p) = world.bodies.frames[0], world.bodies.points[0]
    with pytest.raises(InvalidRequest) as e:
        keep_cloud(world, _spec(world, p @ poses[f][:3, :3].T + poses[f][:3, 3]), STATE)
    assert e.value.field == "add[0].points" and e.value.details["filtered_robot"] > 0


def test_unknown_occupied_adds_the_shadow_but_not_in_the_robot(world):
    # a camera above and behind the arm looking down the +x axis at a wall 2 m ahead
    rng = np.random.default_rng(5)
    wall = np.column_stack([np.full(20_000, 2.0), rng.uniform(-1, 1, 20_000),
                            rng.uniform(0, 2, 20_000)])
    camera = {"xyz": [-0.8, 0.0, 1.0], "hfov": 1.0, "vfov": 0.8, "range": 3.0}
    kept = keep_cloud(world, _spec(world, wall, unknown="occupied", camera=camera), STATE)
    assert [b.id for b in kept.bodies] == ["cam", "cam.unknown"] and kept.shadow > 0
    dark = kept.bodies[1].cells
    assert (dark.centers[:, 0] > 2.0).any()  # behind the wall
    w = world.with_scene(clouds=kept.bodies)
    assert w.is_valid(STATE)  # the arm hides space but is not inside its shadow
    assert kept.reply()["unknown"] == "occupied"


@pytest.mark.parametrize("extra,field", [
    ({"frame": "no_such_link"}, "add[0].frame"),
    ({"resolution": 0.5}, "add[0].resolution"),
    ({"unknown": "occupied"}, "add[0].camera"),
    ({"unknown": "maybe"}, "add[0].unknown"),
    ({"unknown": "occupied", "camera": {"link": "nope", "hfov": 1, "vfov": 1, "range": 1}},
     "add[0].camera.link"),
    ({"padding": -0.1}, "add[0].padding"),
    ({"colour": "red"}, "add[0]"),
])
def test_bad_cloud_objects_are_refused_naming_the_field(world, extra, field):
    with pytest.raises(InvalidRequest) as e:
        _spec(world, np.zeros((3, 3)), **extra)
    assert e.value.field == field
