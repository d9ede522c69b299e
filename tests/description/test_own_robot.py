"""A user's own ROS 2 workspace, end to end through a real `arduinobot serve`.

The workspace is what ROS 2 and the MoveIt Setup Assistant leave behind (see
tests/helpers/course_workspace.py): a multi-file xacro with ros2_control and gazebo tags
and $(find other_package), millimetre CAD meshes with open edges, a camera on a fixed
joint, no config/ in the description package, and a separate arduinobot_moveit package
whose SRDF is stale (no camera pairs), names `home` twice and whose joint_limits.yaml
scales speeds to 0.1 by default.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.description import load_description
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.chain import Kinematics
from tests.helpers.cli import run_cli
from tests.helpers.serve import start_server

ARM = ("joint_1", "joint_2", "joint_3")


@pytest.fixture(scope="module")
def published(course_ws, tmp_path_factory):
    """`serve --moveit-config` on the workspace as published."""
    cache = tmp_path_factory.mktemp("cache")
    srv = start_server(["--workers", "2", str(course_ws.xacro), "--package-dir",
                        str(course_ws.src), "--moveit-config", str(course_ws.moveit_pkg),
                        "--cache-dir", str(cache)], timeout=240)
    with PlannerClient(srv.endpoint, timeout=60) as c:
        yield srv, c
    srv.stop()


@pytest.fixture(scope="module")
def local(course_ws):
    return load_description(course_ws.xacro, package_dirs=[course_ws.src],
                            moveit_config=course_ws.moveit_pkg, env={})


def test_check_passes_with_warnings_only(course_ws):
    r = run_cli("check", str(course_ws.xacro), "--package-dir", str(course_ws.src), "--json")
    report = json.loads(r.stdout)
    fails = [f for f in report["findings"] if f["level"] == "FAIL"]
    assert r.returncode == 0 and not fails, fails
    warns = {(f["check"], f["message"]) for f in report["findings"] if f["level"] == "WARN"}
    assert any(c == "mesh" and "not watertight" in m for c, m in warns)
    assert any("<material> inside <geometry>" in m for _, m in warns)
    config = next(f for f in report["findings"] if f["check"] == "config")
    # found without --moveit-config: the MoveIt package named after the robot
    assert config["level"] == "PASS" and "arduinobot_moveit" in config["message"]


def test_info_names_the_files_the_tcp_and_the_scaling(course_ws):
    r = run_cli("info", str(course_ws.xacro), "--package-dir", str(course_ws.src))
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "config: package arduinobot_moveit (named after the robot)" in out
    assert "arduinobot.srdf" in out and "joint_limits.yaml" in out
    assert "tcp: (0.0, 0.0, 0.0) in claw_support [default: origin of claw_support" in out
    assert "default scaling: velocity x0.1, acceleration x0.1" in out
    assert "named state home (arm)" in out and "named state home (gripper)" in out


def test_the_loader_reads_moveit_semantics(local):
    assert local.config.moveit_package is not None
    assert (local.default_velocity_scaling, local.default_acceleration_scaling) == (0.1, 0.1)
    assert local.srdf.groups["arm"].joints == ARM  # virtual and fixed joints ignored
    assert local.tcp.parent_link == "claw_support"
    acm = CollisionWorld(local).acm
    # joined by a fixed joint: allowed although the stale SRDF never mentions the camera
    assert acm.reason("base_link", "rgb_camera_link") == "Adjacent"
    assert not acm.allowed("rgb_camera_link", "horizontal_arm")


@pytest.mark.slow
def test_service_reports_the_config_and_the_robot(published):
    _, c = published
    h = c.health()
    assert h["config"]["srdf"].endswith("arduinobot_moveit/config/arduinobot.srdf")
    assert h["config"]["found_by"] == "--moveit-config"
    d = c.description()
    assert set(d["groups"]) == {"arm", "gripper", "all"} and d["default_group"] == "arm"
    homes = {s["group"] for s in d["named_states"] if s["name"] == "home"}
    assert homes == {"arm", "gripper"}
    assert d["default_scaling"] == {"velocity": 0.1, "acceleration": 0.1}
    assert d["tcp"]["parent_link"] == "claw_support"
    assert c.schema()["robot"]["groups"]["arm"] == list(ARM)


@pytest.mark.slow
def test_named_home_for_the_arm_plans_from_a_bent_start_to_zero(published):
    _, c = published
    start = {"joint_1": 0.6, "joint_2": 0.4, "joint_3": -0.5}
    res = c.plan(goal={"named": "home"}, group="arm", start=start, seed=1)
    end = dict(zip(res.joint_names, res.positions[-1]))
    assert all(abs(end[j]) < 1e-9 for j in ARM)
    with pytest.raises(errors.InvalidRequest) as e:
        c.plan(goal={"named": "home"}, start=start)
    assert e.value.details["field"] == "goal.named"
    assert "ambiguous" in e.value.message and "arm, gripper" in e.value.message


@pytest.mark.slow
def test_position_goal_without_a_tcp_file_reaches_the_tip_link(published, local):
    _, c = published
    kin = Kinematics(local.robot)
    target_q = np.array([0.4, 0.3, 0.5, 0.0])
    target = kin.link_poses(target_q)[kin.link_index["claw_support"], :3, 3]
    res = c.plan(goal={"position": target.tolist()}, seed=2)
    q = np.asarray(res.positions[-1])
    reached = kin.link_poses(q)[kin.link_index["claw_support"], :3, 3]
    assert np.linalg.norm(reached - target) < 1e-6  # the IK tests' tolerance


@pytest.mark.slow
def test_default_scaling_applies_and_a_request_scaling_replaces_it(published):
    _, c = published
    full = c.description()["limits"]
    start = {"joint_1": -0.5, "joint_2": 0.2, "joint_3": 0.3}
    goal = {"joints": {"joint_1": 0.5, "joint_2": 0.0, "joint_3": 0.0}}
    slow = c.plan(goal=goal, start=start, seed=3)
    fast = c.plan(goal=goal, start=start, seed=3, velocity_scaling=1.0,
                  acceleration_scaling=1.0)
    for res, factor in ((slow, 0.1), (fast, 1.0)):
        for k, name in enumerate(res.joint_names):
            assert np.abs(res.velocities[:, k]).max() <= factor * full[name]["velocity"] + 1e-6
            assert np.abs(res.accelerations[:, k]).max() <= \
                factor * full[name]["acceleration"] + 1e-6
    assert slow.duration > 2 * fast.duration


@pytest.mark.slow
def test_random_arm_goals_are_free_or_really_in_collision(published, local):
    _, c = published
    # the independent check: the same meshes, only joint-connected and SRDF pairs allowed,
    # and the ground every plan has (issue 38, item 5)
    # (links that never move stand on it)
    from arduinobot.scene.ground import GROUND_ID, ground_obstacle
    bare = CollisionWorld(local)
    on_ground = [(GROUND_ID, n) for n, still in zip(bare.bodies.names, bare.bodies.statics)
                 if still]
    world = bare.with_scene((ground_obstacle(),),
                            acm=bare.acm.with_pairs(on_ground, reason="Ground"))
    lim = local.robot.position_limits(ARM)
    rng = np.random.default_rng(7)
    planned = refused = 0
    for i in range(6):
        goal = dict(zip(ARM, rng.uniform(lim[:, 0], lim[:, 1]).tolist()))
        try:
            res = c.plan(goal={"joints": goal}, seed=i, planning_time=5.0)
        except errors.GoalInCollision as e:
            q = np.array([goal["joint_1"], goal["joint_2"], goal["joint_3"], 0.0])
            assert not world.check(q).valid, e.details
            refused += 1
            continue
        planned += 1
        dense = interpolate(np.asarray(res.positions), 0.002)
        assert world.first_invalid(dense) == -1
    assert planned >= 1


@pytest.mark.slow
def test_without_any_srdf_the_camera_and_adjacent_links_are_not_collisions(
        course_ws, tmp_path_factory):
    # the same workspace with the MoveIt package removed: no SRDF anywhere
    src = tmp_path_factory.mktemp("bare") / "src"
    shutil.copytree(course_ws.src, src, ignore=shutil.ignore_patterns("arduinobot_moveit"))
    xacro = src / course_ws.xacro.relative_to(course_ws.src)
    d = load_description(xacro, package_dirs=[src], env={})
    assert d.srdf is None and d.tcp.parent_link == "claw_support"
    srv = start_server(["--workers", "1", str(xacro), "--package-dir", str(src),
                        "--cache-dir", str(tmp_path_factory.mktemp("cache"))], timeout=240)
    try:
        with PlannerClient(srv.endpoint, timeout=60) as c:
            assert c.check_state({}).valid  # at zero nothing collides
            res = c.plan(goal={"joints": {"joint_1": 0.8, "joint_2": 0.3, "joint_3": 0.4}},
                         seed=4)
            assert res.duration > 0
            # no SRDF: the groups are derived, and the default is the arm without the
            # gripper (issue 38, item 3: `ik` must not move the jaw)
            desc = c.description()
            assert desc["default_group"] == "arm"
            assert "joint_4" not in desc["groups"]["arm"]
    finally:
        srv.stop()


@pytest.mark.slow
def test_fk_and_ik_use_the_default_tcp(published, local):
    _, c = published
    kin = Kinematics(local.robot)
    q = {"joint_1": -0.3, "joint_2": 0.5, "joint_3": 0.2}
    tip = kin.link_poses(np.array([q[j] for j in ARM] + [0.0]))[kin.link_index["claw_support"]]
    assert np.allclose(c.fk(q).tcp, tip[:3, 3], atol=1e-9)
    sols = c.ik(tip[:3, 3].tolist()).solutions
    assert sols
    for s in sols:
        got = c.fk(s.joints).tcp
        assert np.linalg.norm(np.asarray(got) - tip[:3, 3]) < 1e-6
