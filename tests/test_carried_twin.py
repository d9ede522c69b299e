"""The MuJoCo twin with the kept scene (issue 28 item 3): scene objects (meshes too) in its
world, a carried object welded inside its link with its mass: where the planner says it
is, its weight on the servos (by hand: the torque of a point mass about each joint's
axis), its contacts with the scene reported and with its touch links not."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import trimesh

from execution.robots.sim_arduinobot import SimArduinobot
from planner.scene import Obstacle
from service.disk_cache import DiskCache

from .helpers.carry import shipped_case
from .helpers.fk import link_pose

CACHE = DiskCache()
case = pytest.fixture(shipped_case, scope="module", name="case")


def test_the_carried_box_is_welded_where_its_link_holds_it_with_its_mass(case):
    state = {"joint_1": -0.8, "joint_2": 0.3}
    sim = SimArduinobot(case.d, cache=CACHE, attached=[case.attached(0.2)],
                        initial=list(case.q(state)))
    m, d = sim.model, sim.data
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "carried:carried_box")
    geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "carried:carried_box")
    assert body >= 0 and geom >= 0
    assert m.body_mass[body] == pytest.approx(0.2)
    assert m.body_jntnum[body] == 0  # welded: no joint of its own
    want = link_pose(case.d.robot, case.link, case.names, case.q(state)) @ case.box.pose()
    assert np.allclose(d.geom_xpos[geom], want[:3, 3], atol=1e-9)
    assert np.allclose(d.geom_xmat[geom].reshape(3, 3), want[:3, :3], atol=1e-9)
    # its weight on the servos: holding torque with it minus without it is the torque of
    # 0.2 kg at its centre (the box's centre) about each joint's axis, by hand
    bare = SimArduinobot(case.d, cache=CACHE, initial=list(case.q(state)))
    zero = np.zeros(len(case.names))
    extra = sim._inverse(case.q(state), zero, zero) - bare._inverse(case.q(state), zero,
                                                                      zero)
    weight = np.array([0.0, 0.0, -9.81 * 0.2])
    above = {j.name for j in case.d.robot.link_path(case.link)}  # the joints that carry it
    for i, name in enumerate(case.names):
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        axis, anchor = d.xaxis[j], d.xanchor[j]
        hand = -float(axis @ np.cross(want[:3, 3] - anchor, weight)) if name in above else 0.0
        assert extra[i] == pytest.approx(hand, abs=1e-6), name
    assert abs(extra[1]) > 1e-3  # the shoulder does feel it


def test_set_scene_puts_scene_objects_in_the_world_and_reports_the_carried_contacts(
        case, tmp_path):
    sim = SimArduinobot(case.d, cache=CACHE)
    mesh = tmp_path / "bin.stl"
    mesh.write_bytes(trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(file_type="stl"))
    bin_ = Obstacle("bin", "mesh", mesh_path=str(mesh), xyz=(3.0, 3.0, 3.0))
    # at 0 the carried box is in the table (tests/test_carried.py's case)
    sim.set_scene([case.table, bin_], [case.attached(0.2)])
    m = sim.model
    names = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m.ngeom)}
    assert "obstacle:table" in names and any(n and n.startswith("obstacle:bin/")
                                             for n in names)
    touching = sim.contacts_now()
    assert ("carried:carried_box", "obstacle:table") in touching, touching
    assert not any("carried:carried_box" in p and case.link in p for p in touching)
    # away from the table (as the planner says: free at -0.8) it touches nothing
    sim.set_scene([case.table, bin_], [case.attached(0.2)])
    sim.reset(case.q({"joint_1": -0.8}))
    assert not any("carried:carried_box" in p for p in sim.contacts_now())
    # put down: no carried body any more
    sim.set_scene([case.table])
    assert mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, "carried:carried_box") < 0


def test_the_execute_service_gives_its_twin_the_kept_scene_when_it_changes(case):
    from execution.robots.spec import RobotSpec
    from service.execution import ExecuteService
    from service.scene_store import SceneSnapshot

    sim = SimArduinobot(case.d, cache=CACHE)
    svc = ExecuteService(None, "p", case.d, RobotSpec())  # no session: nothing served
    snaps = [SceneSnapshot(3, (case.table,), (case.attached(0.2),))]
    svc.scene_source = lambda: snaps[-1]
    svc._scene_to_twin(sim, [])
    m = sim.model
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "carried:carried_box") >= 0
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "obstacle:table") >= 0
    svc._scene_to_twin(sim, [])
    assert sim.model is m  # the same scene: not rebuilt
    own = {"id": "post", "shape": "cylinder", "radius": 0.02, "length": 0.5, "xyz": [3, 0, 0]}
    svc._scene_to_twin(sim, [own])  # a plan's own obstacle too
    assert mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, "obstacle:post") >= 0
    snaps.append(SceneSnapshot(4))  # detached and cleared
    svc._scene_to_twin(sim, [])
    assert mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, "carried:carried_box") < 0
    assert mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, "obstacle:table") < 0
