"""The MuJoCo twin: built from the loaded description, stepped for real."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.execution.executor import ExecuteOptions, Executor
from arduinobot.execution.robots.mjcf import Gains
from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
from arduinobot.execution.segments import SampledTrajectory
from arduinobot.service.process.disk_cache import DiskCache

#: the twin's mesh pieces, computed once per machine as the command line keeps them
CACHE = DiskCache()


@pytest.fixture(scope="module")
def planner(desc):
    from arduinobot.planner.planning.pipeline import MotionPlanner
    return MotionPlanner(desc)


def plan(planner, name, seed=5, **kw):
    from arduinobot.planner.planning.goals import NamedGoal
    from arduinobot.planner.planning.pipeline import MotionRequest
    return planner.solve(MotionRequest(goal=NamedGoal(name), seed=seed, **kw)).trajectory


def test_the_model_is_the_description(desc):
    sim = SimArduinobot(desc, cache=CACHE)
    m = sim.model
    robot = desc.robot
    for name in robot.actuated_joints + robot.mimic_joints:
        j = robot.joints[name]
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert tuple(m.jnt_range[jid]) == pytest.approx((j.limit.lower, j.limit.upper))
    for name, link in robot.links.items():
        if link.inertial is None or name == "world":
            continue
        bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        assert m.body_mass[bid] == pytest.approx(link.inertial.mass)
        assert sorted(m.body_inertia[bid]) == pytest.approx(
            sorted(np.linalg.eigvalsh(link.inertial.tensor())))
    # every collision mesh, as convex pieces on its own link; besides, the ground's plane
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "obstacle:ground")
    assert floor >= 0 and m.geom_type[floor] == mujoco.mjtGeom.mjGEOM_PLANE
    assert int(np.sum(m.geom_type == mujoco.mjtGeom.mjGEOM_MESH)) == m.ngeom - 1
    for name, link in robot.links.items():
        if link.collisions:
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
            assert 1 <= int(np.sum(m.geom_bodyid == bid)) <= 32 * len(link.collisions)
    assert sim.contacts_now() == []  # the closed gripper's pieces do not touch
    for i, name in enumerate(robot.actuated_joints):
        aid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        eff = robot.joints[name].limit.effort
        assert tuple(m.actuator_forcerange[aid]) == (-eff, eff)
        assert sim.gains[i].kp > 0 and sim.gains[i].kv > 0
    assert m.neq == 1  # joint_5 = -joint_4


def test_mimic_follows_and_servos_hold_against_gravity(desc):
    sim = SimArduinobot(desc, cache=CACHE)
    q = np.array([0.4, 0.6, -0.5, -1.0])
    for k in range(1, 201):  # a slow ramp over 2 s, then 1 s of holding
        sim.command(q * min(1.0, k / 100))
        sim.advance(0.01)
    for _ in range(100):
        sim.command(q)
        sim.advance(0.01)
    st = sim.state()
    pos = dict(zip(st.names, st.positions))
    assert [pos[n] for n in ("joint_1", "joint_2", "joint_3", "joint_4")] == pytest.approx(
        q, abs=1e-3)
    assert pos["joint_5"] == pytest.approx(-pos["joint_4"], abs=1e-3)
    assert max(abs(v) for v in st.velocities) < 1e-3
    assert st.stamp == pytest.approx(3.0)


@pytest.mark.parametrize("goal", ["reach_left", "reach_forward", "reach_right"])
def test_a_plan_replays_within_its_limits(desc, planner, goal):
    traj = plan(planner, goal)
    body = {"trajectory": traj.to_dict()}
    sim = SimArduinobot(desc, cache=CACHE)
    rep = Executor.for_description(sim, desc, options=ExecuteOptions(realtime=False)).execute(
        SampledTrajectory.from_json(body))
    st = sim.stats()
    err = max(rep.max_tracking_error)
    final = np.abs(rep.measured[-1] - traj.positions[-1]).max()
    print(f"\n{goal}: {traj.duration:.3f} s, tracking error {1000 * err:.3f} mrad, final "
          f"{1000 * final:.3f} mrad, peak force {np.round(st.peak_force, 2)} of "
          f"{st.effort}, saturated {st.saturated_steps}/{st.steps} steps, contacts "
          f"{st.contacts}")
    assert err < 2e-3  # rad
    assert final < 1e-3
    assert max(f / e for f, e in zip(st.peak_force, st.effort)) < 1.0
    assert st.saturated_steps == 0
    assert max(f / e for f, e in zip(st.peak_feedforward, st.effort)) <= 1 + 1e-3
    assert st.contacts == ()


def test_contacts_with_an_obstacle_are_reported(desc, planner):
    traj = plan(planner, "reach_forward")
    tip = traj.positions[-1]
    # a ball where the claw ends up: the plan ignored it, the twin must not
    from arduinobot.planner.kinematics.chain import Kinematics
    kin = Kinematics(desc.robot)
    xyz = kin.link_poses(tip)[kin.link_index["claw_support"]][:3, 3]
    ball = {"id": "ball", "shape": "sphere", "radius": 0.15, "xyz": [float(v) for v in xyz]}
    sim = SimArduinobot(desc, cache=CACHE, obstacles=[ball])
    Executor.for_description(sim, desc, options=ExecuteOptions(realtime=False)).execute(
        SampledTrajectory.from_json({"trajectory": traj.to_dict()}))
    st = sim.stats()
    assert any("obstacle:ball" in p for p in st.contacts), st.contacts
    assert st.contact_steps > 0


def test_gains_come_from_the_controllers_yaml(desc, tmp_path):
    y = tmp_path / "arduinobot_controllers.yaml"
    y.write_text("arm_controller:\n  ros__parameters:\n    joints: [joint_1, joint_2]\n"
                 "    command_interfaces: [effort]\n"
                 "    gains:\n      joint_1: {p: 800.0, d: 12.5, i: 0.0}\n"
                 "      joint_2: {p: 900.0}\n"
                 "gripper_controller:\n  ros__parameters:\n    joints: [joint_4]\n"
                 "    command_interfaces: [position]\n"
                 "    gains:\n      joint_4: {p: 1.0, d: 0.1}\n")
    sim = SimArduinobot(desc, cache=CACHE, controllers=y)
    assert sim.gains[0] == Gains(800.0, 12.5)
    assert sim.gains[1] == Gains(900.0, 0.0)
    assert "default" in sim.gain_source["joint_3"]
    assert "default" in sim.gain_source["joint_4"]  # position-commanded: gains unused
    aid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_ACTUATOR, "joint_1")
    assert sim.model.actuator_gainprm[aid, 0] == 800.0
    assert tuple(sim.model.actuator_biasprm[aid, :3]) == (0.0, -800.0, -12.5)


def test_default_servo_bandwidth(desc):
    sim = SimArduinobot(desc, cache=CACHE, bandwidth=10.0)
    full = np.zeros((sim.model.nv, sim.model.nv))
    mujoco.mj_fullM(sim.model, sim.data, full)
    w = 2 * math.pi * 10.0
    assert sim.gains[0].kp == pytest.approx(full[0, 0] * w * w)
    assert sim.gains[0].kv == pytest.approx(2 * full[0, 0] * w)


def test_plan_simulate_reports_and_plots(tmp_path):
    import subprocess
    import sys

    from tests.helpers.serve import REPO
    png = tmp_path / "sim.png"
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "plan", "--named", "reach_right",
                        "--local", "--simulate", "--plot", str(png), "--obstacle",
                        "box:table:0.6,1.2,0.05@0,1.0,0.6"], cwd=REPO, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "simulation (MuJoCo twin)" in r.stdout and "contacts: none" in r.stdout
    assert "of the effort limit" in r.stdout
    assert png.stat().st_size > 10_000


def test_the_course_workspace_twin_and_port(course_ws):
    """The course's own packages: its controllers yaml (position-commanded, so its PID
    gains do not apply) is found, the twin holds the arm, and the serial port comes from
    the real-robot ros2_control block."""
    from arduinobot.execution.robots.base import PortNotFound
    from arduinobot.execution.robots.controller_gains import find_controllers_yaml
    from arduinobot.execution.robots.serial_arduinobot import SerialArduinobot
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src])
    assert find_controllers_yaml(d).name == "arduinobot_controllers.yaml"
    sim = SimArduinobot(d, cache=CACHE)
    assert all("default" in sim.gain_source[n] for n in sim.joint_names)
    for _ in range(100):
        sim.command([0.0] * len(sim.joint_names))
        sim.advance(0.01)
    # held against gravity by the 10 Hz servos (the yaml's p = 1 N m/rad would let it fall)
    assert np.abs(sim.state().actuated(sim.joint_names)).max() < 5e-3
    with pytest.raises(PortNotFound, match="is_sim=false"):
        SerialArduinobot.from_description(d)  # is_sim defaults to true: Gazebo's block
    real = load_description(course_ws.xacro, package_dirs=[course_ws.src],
                            args={"is_sim": "false"})
    with pytest.raises(PortNotFound, match="/dev/ttyACM0") as e:
        SerialArduinobot.from_description(real)
    assert e.value.details["port"] == "/dev/ttyACM0"


def test_convex_pieces_are_cached_and_cover_the_mesh(tmp_path):
    import trimesh

    from arduinobot.description.packages import SHIPPED_PACKAGE_DIR
    from arduinobot.execution.robots.mjcf import cluster_parts, mesh_parts
    from arduinobot.service.process.disk_cache import DiskCache
    path = SHIPPED_PACKAGE_DIR / "meshes" / "right_finger.STL"
    cache = DiskCache(tmp_path)
    first = mesh_parts(path, (0.01, 0.01, 0.01), 32, cache=cache)
    assert 1 < len(first) <= 32 and list(tmp_path.glob("mujoco_hulls/*.npz"))
    again = mesh_parts(path, (0.01, 0.01, 0.01), 32, cache=cache)
    assert len(again) == len(first)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    # the V-HACD pieces hug the part: their bounding box is the mesh's within 1% of the
    # part's size (an approximation: it shaves corners, 2.9 mm of 0.58 m on this finger)
    m = trimesh.load(path, force="mesh")
    lo, hi = np.asarray(m.bounds) * 0.01
    tol = 0.01 * float(np.max(hi - lo))
    allv = np.vstack(first)
    assert np.all(np.abs(allv.min(axis=0) - lo) <= tol)
    assert np.all(np.abs(allv.max(axis=0) - hi) <= tol)
    # the fallback's pieces hold every vertex of the surface
    pieces = cluster_parts(path, (0.01, 0.01, 0.01), 16)
    have = {tuple(np.round(v, 9)) for p in pieces for v in p}
    assert all(tuple(np.round(v, 9)) in have for v in np.asarray(m.vertices) * 0.01)


def test_the_twin_before_it_opens_is_where_it_opens(desc):
    """What the service answers on robot_state before the twin is built (twin_start):
    the state the twin has when it opens, mimics following, at rest."""
    from dataclasses import replace

    from arduinobot.execution.robots.spec import twin_start
    d = replace(desc, initial_positions={"joint_1": 0.3, "joint_3": -0.2, "joint_4": -0.4})
    before = twin_start(d)
    opened = SimArduinobot(d, cache=CACHE).state()
    assert before.names == opened.names and "joint_5" in before.names
    assert np.allclose(before.positions, opened.positions, atol=1e-12)
    assert before.positions[before.names.index("joint_5")] == pytest.approx(0.4)
    assert before.velocities == (0.0,) * len(before.names) and before.efforts is None
