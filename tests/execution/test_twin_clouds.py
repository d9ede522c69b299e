"""A kept point cloud in the MuJoCo twin (execution/robots/twin_clouds.py): its cells as
static boxes, the same union the planner checks, capped nearest first with a warning; a
state the planner finds colliding with the cloud touches it in the twin, and a free one
does not."""

from __future__ import annotations

import logging

import numpy as np

from arduinobot.execution.robots.mjcf import Gains, to_mjcf
from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
from arduinobot.execution.robots.twin_clouds import cloud_boxes
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.scene.cloud import Cells, CloudObstacle, voxelise
from arduinobot.service.process.disk_cache import DiskCache

CACHE = DiskCache()


def _cells_of(center, half) -> set[tuple[int, int, int]]:
    # every 1 cm cell inside boxes given by centres and half sizes [m]
    out = set()
    for c, h in zip(np.round((center - half) / 0.01).astype(int),
                    np.round(2 * half / 0.01).astype(int)):
        g = np.mgrid[c[0]:c[0] + h[0], c[1]:c[1] + h[1], c[2]:c[2] + h[2]].reshape(3, -1).T
        out |= set(map(tuple, g.tolist()))
    return out


def test_the_boxes_are_the_cells_union_and_a_cap_keeps_the_nearest(caplog):
    rng = np.random.default_rng(3)
    idx = np.unique(rng.integers(-40, 40, (3000, 3)), axis=0)
    cloud = CloudObstacle("camera", Cells(idx, 0.01))
    [(cid, center, half)] = cloud_boxes([cloud])
    assert cid == "camera" and len(center) < len(idx)
    assert _cells_of(center, half) == set(map(tuple, idx.tolist()))
    with caplog.at_level(logging.WARNING):
        [(_, near, nhalf)] = cloud_boxes([cloud], cap=100)
    assert len(near) == 100
    assert "cloud 'camera' as 100 of its" in caplog.text
    gap = np.linalg.norm(np.maximum(np.abs(center) - half, 0), axis=1)
    kept = np.linalg.norm(np.maximum(np.abs(near) - nhalf, 0), axis=1)
    assert kept.max() <= np.sort(gap)[99] + 1e-12  # the nearest hundred


def test_the_twin_touches_the_cloud_where_the_planner_finds_it(desc):
    kin = Kinematics(desc.robot)
    home = np.zeros(kin.dof)
    reach = np.array([0.0, 0.9, 0.6, 0.0])[:kin.dof]
    claw = kin.link_poses(reach)[kin.link_index["claw_support"]][:3, 3]
    # a measured 12 cm block of points around where the claw is at `reach`
    rng = np.random.default_rng(4)
    cells, _ = voxelise(claw + rng.uniform(-0.06, 0.06, (20_000, 3)), 0.01)
    cloud = CloudObstacle("camera", cells)
    world = CollisionWorld(desc).with_scene(clouds=[cloud])
    assert world.is_valid(home) and not world.is_valid(reach)  # the check can fail
    gains = {n: Gains(1.0, 0.0) for n in kin.joint_names}
    xml = to_mjcf(desc.robot, gains=gains, obstacles=[cloud])
    assert xml.count('name="obstacle:camera/') == len(cloud_boxes([cloud])[0][1])
    sim = SimArduinobot(desc, cache=CACHE, obstacles=[cloud])
    joints = list(sim.joint_names)
    sim.reset([dict(zip(kin.joint_names, home)).get(n, 0.0) for n in joints])
    assert not any("obstacle:camera" in a or "obstacle:camera" in b
                   for a, b in sim.contacts_now())
    sim.reset([dict(zip(kin.joint_names, reach)).get(n, 0.0) for n in joints])
    touching = [p for p in sim.contacts_now() if any(n.startswith("obstacle:camera/")
                                                    for n in p)]
    assert touching, sim.contacts_now()
