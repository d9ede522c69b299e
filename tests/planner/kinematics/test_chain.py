"""Forward kinematics against yourdfpy, batch against single, mimic applied."""

from __future__ import annotations

import numpy as np
import pytest
import yourdfpy

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import load_description
from arduinobot.planner.kinematics.chain import Kinematics
from tests.helpers.user_package import make_user_package


def _yourdfpy(d) -> yourdfpy.URDF:
    pkgs = d.robot.package_dirs

    def handler(fname: str) -> str:
        if fname.startswith("package://"):
            pkg, _, rel = fname[len("package://"):].partition("/")
            return str(pkgs[pkg] / rel)
        return fname

    return yourdfpy.URDF(robot=yourdfpy.URDF._parse_robot(
        yourdfpy.urdf.etree.fromstring(d.robot.urdf.encode())), filename_handler=handler,
        load_meshes=False, build_collision_scene_graph=False, load_collision_meshes=False)


def test_fk_matches_yourdfpy(desc):
    kin = Kinematics(desc.robot)
    ref = _yourdfpy(desc)
    assert tuple(ref.actuated_joint_names) == kin.joint_names
    lim = desc.robot.position_limits()
    rng = np.random.default_rng(7)
    worst = 0.0
    for q in rng.uniform(lim[:, 0], lim[:, 1], size=(200, kin.dof)):
        ref.update_cfg(q)
        poses = kin.link_poses(q)
        for i, link in enumerate(kin.link_names):
            worst = max(worst, float(np.abs(poses[i] - ref.get_transform(link, "world")).max()))
    assert worst < 1e-9


def test_batch_equals_single_and_buffer_reuse(desc):
    kin = Kinematics(desc.robot)
    qs = np.random.default_rng(1).uniform(-1.5, 0.0, size=(50, kin.dof))
    batch = kin.link_poses_batch(qs)
    buf = np.empty((len(kin.link_names), 4, 4))
    for q, b in zip(qs, batch):
        assert np.array_equal(kin.link_poses(q, out=buf), b)


def test_mimic_moves_left_finger_opposite(desc):
    kin = Kinematics(desc.robot)
    q = np.array([0.0, 0.0, 0.0, -0.5])
    poses = kin.link_poses(q)
    claw = poses[kin.link_index["claw_support"]]
    right = np.linalg.inv(claw) @ poses[kin.link_index["gripper_right"]]
    left = np.linalg.inv(claw) @ poses[kin.link_index["gripper_left"]]
    yaw_r = np.arctan2(right[1, 0], right[0, 0])
    yaw_l = np.arctan2(left[1, 0], left[0, 0])
    assert yaw_r == pytest.approx(-0.5) and yaw_l == pytest.approx(0.5)


def test_prismatic_and_user_robot(tmp_path):
    pkg = make_user_package(tmp_path, fine_faces=2000)
    d = load_description(pkg / "urdf" / "my_bot.urdf.xacro", package_dirs=[pkg], env={})
    kin = Kinematics(d.robot)
    ref = _yourdfpy(d)
    for q in np.random.default_rng(3).uniform([-1, 0], [1, 0.2], size=(20, 2)):
        ref.update_cfg(q)
        for i, link in enumerate(kin.link_names):
            assert np.allclose(kin.link_poses(q)[i], ref.get_transform(link, d.robot.root),
                               atol=1e-9)


def test_bad_input(desc):
    kin = Kinematics(desc.robot)
    with pytest.raises(InvalidRequest, match="expected 4 joint values"):
        kin.link_poses([0.0, 0.0])
    with pytest.raises(InvalidRequest, match="not an actuated joint"):
        Kinematics(desc.robot, ["joint_5"])
    with pytest.raises(InvalidRequest, match="no link 'hand'"):
        kin.link_pose(np.zeros(4), "hand")
