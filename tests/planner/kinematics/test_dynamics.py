"""Inverse dynamics against MuJoCo, on the arduinobot and on a robot with prismatic
joints, rotated inertial frames and full inertia tensors."""

from __future__ import annotations

import textwrap

import mujoco
import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Robot, load_description
from arduinobot.description.model import rpy_matrix
from arduinobot.planner.kinematics.dynamics import InverseDynamics


def _quat(rot: np.ndarray) -> str:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot).ravel())
    return " ".join(repr(float(v)) for v in q)


def to_mjcf(robot: Robot) -> str:
    """An MJCF model with the robot's kinematics and inertials, one DOF per movable tree
    joint (mimics unconstrained: the test drives them itself), no geoms, no contacts."""
    def body(link: str, indent: str) -> str:
        out = []
        inertial = robot.links[link].inertial
        if inertial is not None and inertial.mass > 0:
            rot = rpy_matrix(inertial.origin.rpy)
            t = rot @ inertial.tensor() @ rot.T
            full = " ".join(repr(float(v)) for v in
                            (t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]))
            pos = " ".join(repr(float(v)) for v in inertial.origin.xyz)
            out.append(f'{indent}<inertial pos="{pos}" mass="{inertial.mass!r}" '
                       f'fullinertia="{full}"/>')
        for j in robot.child_joints[link]:
            pos = " ".join(repr(float(v)) for v in j.origin.xyz)
            out.append(f'{indent}<body name="{j.child}" pos="{pos}" '
                       f'quat="{_quat(rpy_matrix(j.origin.rpy))}">')
            if j.movable:
                kind = "slide" if j.type == "prismatic" else "hinge"
                axis = " ".join(repr(float(v)) for v in j.axis)
                out.append(f'{indent}  <joint name="{j.name}" type="{kind}" axis="{axis}" '
                           'limited="false" damping="0" armature="0"/>')
            out.append(body(j.child, indent + "  "))
            out.append(f"{indent}</body>")
        return "\n".join(o for o in out if o)

    return (f'<mujoco model="{robot.name}">\n'
            '  <option gravity="0 0 -9.81"/>\n'
            '  <compiler angle="radian" balanceinertia="false" boundmass="0" '
            'boundinertia="0"/>\n'
            f"  <worldbody>\n{body(robot.root, '    ')}\n  </worldbody>\n</mujoco>\n")


class MujocoReference:
    """MuJoCo's inverse dynamics with mimics driven by their leaders and folded in."""

    def __init__(self, robot: Robot, dyn: InverseDynamics) -> None:
        self.model = mujoco.MjModel.from_xml_string(to_mjcf(robot))
        self.data = mujoco.MjData(self.model)
        self.dof = dyn.dof
        # map: mujoco dof -> (actuated index, multiplier)
        self.map = []
        for d in range(self.model.nv):
            name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_JOINT,
                                     self.model.dof_jntid[d])
            j = robot.joints[name]
            leader, mult = (j.mimic.joint, j.mimic.multiplier) if j.mimic else (name, 1.0)
            self.map.append((dyn.joint_names.index(leader), mult,
                             j.mimic.offset if j.mimic else 0.0))

    def _set(self, q, qd, qdd) -> None:
        for d, (i, mult, off) in enumerate(self.map):
            self.data.qpos[d] = mult * q[i] + off
            self.data.qvel[d] = mult * qd[i]
            self.data.qacc[d] = mult * qdd[i]

    def torques(self, q, qd, qdd) -> np.ndarray:
        self._set(q, qd, qdd)
        mujoco.mj_inverse(self.model, self.data)
        tau = np.zeros(self.dof)
        for d, (i, mult, _) in enumerate(self.map):
            tau[i] += mult * self.data.qfrc_inverse[d]
        return tau

    def mass_matrix(self, q) -> np.ndarray:
        z = np.zeros(self.dof)
        self._set(q, z, z)
        mujoco.mj_forward(self.model, self.data)
        full = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, full)  # MuJoCo 4 signature
        # fold the mimic DOFs: M_q = S^T M S with qdot_full = S qdot
        s = np.zeros((self.model.nv, self.dof))
        for d, (i, mult, _) in enumerate(self.map):
            s[d, i] = mult
        return s.T @ full @ s


@pytest.fixture(scope="module")
def arduinobot():
    robot = load_description().robot
    dyn = InverseDynamics(robot)
    return dyn, MujocoReference(robot, dyn)


def random_states(rng, dof, n, lo=-1.5, hi=1.5):
    return (rng.uniform(lo, hi, (n, dof)), rng.uniform(-3, 3, (n, dof)),
            rng.uniform(-10, 10, (n, dof)))


def test_matches_mujoco_on_the_arduinobot(arduinobot):
    dyn, ref = arduinobot
    assert dyn.joint_names == ("joint_1", "joint_2", "joint_3", "joint_4")
    qs, qds, qdds = random_states(np.random.default_rng(0), 4, 200)
    ours = dyn.torques_batch(qs, qds, qdds)
    theirs = np.array([ref.torques(*s) for s in zip(qs, qds, qdds)])
    assert np.max(np.abs(theirs)) > 1.0  # a meaningful comparison, not zeros
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-9)
    for k in range(0, 200, 37):
        np.testing.assert_allclose(dyn.torques(qs[k], qds[k], qdds[k]), ours[k], atol=1e-12)


def test_mimic_torque_is_folded_into_the_leader(arduinobot):
    dyn, ref = arduinobot
    # Only the gripper accelerates; both fingers' inertia loads joint_4.
    q = np.array([0.2, 0.3, -0.4, -0.5])
    tau_a = dyn.torques(q, np.zeros(4), np.array([0, 0, 0, 1.0]))
    tau_0 = dyn.torques(q, np.zeros(4), np.zeros(4))
    # Each finger has izz = 1 kg m^2 about its joint axis through its COM, and the
    # mimic's multiplier -1 enters squared: 1 + (-1)^2 * 1.
    assert tau_a[3] - tau_0[3] == pytest.approx(2.0, abs=1e-12)
    np.testing.assert_allclose(tau_a, ref.torques(q, np.zeros(4), [0, 0, 0, 1.0]), atol=1e-9)


def test_gravity_velocity_product_and_mass_matrix_decompose(arduinobot):
    dyn, ref = arduinobot
    rng = np.random.default_rng(1)
    qs, qds, qdds = random_states(rng, 4, 20)
    for q, qd, qdd in zip(qs, qds, qdds):
        m = dyn.mass_matrix(q)
        np.testing.assert_allclose(m, m.T, atol=0)
        assert np.min(np.linalg.eigvalsh(m)) > 0
        np.testing.assert_allclose(m, ref.mass_matrix(q), atol=1e-9)
        total = m @ qdd + dyn.velocity_product(q, qd) + dyn.gravity(q)
        np.testing.assert_allclose(total, dyn.torques(q, qd, qdd), atol=1e-9)
    np.testing.assert_allclose(dyn.mass_matrix_batch(qs[:3]),
                               [dyn.mass_matrix(q) for q in qs[:3]], atol=1e-12)


def test_gravity_at_home_by_hand(arduinobot):
    # At zero, only joint_2/3 carry gravity moments: weight times lever arm along y.
    dyn, _ = arduinobot
    g = dyn.gravity(np.zeros(4))
    assert g[0] == pytest.approx(0.0, abs=1e-12)
    # COMs at link origins: horizontal_arm at y=0 from joint_3; claw_support at y=0.82;
    # fingers at 0.82 + 0.13. Torque about +x of weight -z at +y is -m g y... the motor
    # holds the opposite: tau = +m g y.
    y3 = 0.05 * 0.82 + 2 * 0.01 * (0.82 + 0.13)
    assert g[2] == pytest.approx(9.81 * y3, rel=1e-12)
    assert g[1] == pytest.approx(9.81 * y3, rel=1e-12)  # joint_2 origin has y = 0 too


def test_path_coefficients_match_toppra_definition(arduinobot):
    dyn, _ = arduinobot
    rng = np.random.default_rng(2)
    p, ps, pss = random_states(rng, 4, 5)
    a, b, c = dyn.path_coefficients(p, ps, pss)
    z = np.zeros(4)
    for k in range(5):
        np.testing.assert_allclose(c[k], dyn.torques(p[k], z, z), atol=1e-12)
        np.testing.assert_allclose(a[k], dyn.torques(p[k], z, ps[k]) - c[k], atol=1e-12)
        np.testing.assert_allclose(b[k], dyn.torques(p[k], ps[k], pss[k]) - c[k], atol=1e-12)


def test_subset_of_joints_holds_the_rest_at_zero(arduinobot):
    dyn, ref = arduinobot
    arm = InverseDynamics(dyn.robot, ("joint_1", "joint_2", "joint_3"))
    qs, qds, qdds = random_states(np.random.default_rng(4), 3, 10)
    pad = np.zeros((10, 1))
    full = dyn.torques_batch(np.hstack([qs, pad]), np.hstack([qds, pad]),
                             np.hstack([qdds, pad]))
    np.testing.assert_allclose(arm.torques_batch(qs, qds, qdds), full[:, :3], atol=1e-12)


def test_invalid_input(arduinobot):
    dyn, _ = arduinobot
    with pytest.raises(InvalidRequest) as e:
        dyn.torques([0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0])
    assert e.value.field == "q"
    with pytest.raises(InvalidRequest) as e:
        dyn.torques([0, 0, 0, 0], [0, np.nan, 0, 0], [0, 0, 0, 0])
    assert e.value.field == "qd"
    with pytest.raises(InvalidRequest):
        dyn.torques_batch(np.zeros((3, 4)), np.zeros((2, 4)), np.zeros((3, 4)))


_URDF = """\
<?xml version="1.0"?>
<robot name="mixed">
  <link name="base"/>
  <link name="a">
    <inertial><origin xyz="0.03 -0.02 0.1" rpy="0.3 -0.2 0.7"/><mass value="1.3"/>
      <inertia ixx="0.05" ixy="0.004" ixz="-0.003" iyy="0.04" iyz="0.002" izz="0.03"/>
    </inertial>
  </link>
  <link name="b">
    <inertial><origin xyz="0.2 0.01 -0.02" rpy="-0.5 0.1 0.2"/><mass value="0.7"/>
      <inertia ixx="0.01" ixy="-0.001" ixz="0.0005" iyy="0.02" iyz="-0.002" izz="0.015"/>
    </inertial>
  </link>
  <link name="c">
    <inertial><origin xyz="0.0 0.05 0.02" rpy="0.1 0.2 0.3"/><mass value="0.4"/>
      <inertia ixx="0.004" ixy="0.0002" ixz="0.0001" iyy="0.003" iyz="0.0003" izz="0.005"/>
    </inertial>
  </link>
  <link name="d">
    <inertial><origin xyz="0.01 0.0 0.03" rpy="0 0 0"/><mass value="0.2"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.0015"/>
    </inertial>
  </link>
  <link name="e">
    <inertial><origin xyz="0.02 0.0 0.0" rpy="0 0.4 0"/><mass value="0.1"/>
      <inertia ixx="0.0005" ixy="0" ixz="0" iyy="0.0004" iyz="0" izz="0.0006"/>
    </inertial>
  </link>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="a"/><origin xyz="0.1 0 0.2" rpy="0.1 0.2 0.3"/>
    <axis xyz="0 0.6 0.8"/><limit lower="-3" upper="3" effort="10" velocity="2"/>
  </joint>
  <joint name="j2" type="prismatic">
    <parent link="a"/><child link="b"/><origin xyz="0 0.1 0.3" rpy="-0.4 0 0.2"/>
    <axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5" effort="100" velocity="1"/>
  </joint>
  <joint name="j3" type="continuous">
    <parent link="b"/><child link="c"/><origin xyz="0.3 0 0" rpy="0 0.5 0"/>
    <axis xyz="0 0 1"/><limit effort="5" velocity="3"/>
  </joint>
  <joint name="j4" type="revolute">
    <parent link="b"/><child link="d"/><origin xyz="0.1 0.1 0" rpy="0 0 0"/>
    <axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="5" velocity="3"/>
  </joint>
  <joint name="j5" type="revolute">
    <parent link="b"/><child link="e"/><origin xyz="0.1 -0.1 0" rpy="0 0 0.2"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="5" velocity="3"/>
    <mimic joint="j4" multiplier="1.5" offset="0.2"/>
  </joint>
</robot>
"""


def test_a_state_has_the_same_torques_in_any_batch(arduinobot, tmp_path):
    # the kernel works through blocks of states: a state's torques are bit for bit the
    # same alone, at any place in a block, in a batch of any size (blocks part-filled)
    path = tmp_path / "mixed.urdf"
    path.write_text(textwrap.dedent(_URDF))
    for dyn in (arduinobot[0], InverseDynamics(load_description(path).robot)):
        qs, qds, qdds = random_states(np.random.default_rng(6), dyn.dof, 200)
        alone = np.array([dyn.torques(*s) for s in zip(qs, qds, qdds)])
        for n in (1, 3, 63, 64, 65, 129, 200):
            for start in (0, 7):
                sl = slice(start, start + n)
                np.testing.assert_array_equal(
                    dyn.torques_batch(qs[sl], qds[sl], qdds[sl]), alone[sl])


def test_matches_mujoco_on_a_mixed_robot(tmp_path):
    path = tmp_path / "mixed.urdf"
    path.write_text(textwrap.dedent(_URDF))
    robot = load_description(path).robot
    dyn = InverseDynamics(robot)
    ref = MujocoReference(robot, dyn)
    assert dyn.joint_names == ("j1", "j2", "j3", "j4")
    qs, qds, qdds = random_states(np.random.default_rng(5), 4, 100)
    ours = dyn.torques_batch(qs, qds, qdds)
    theirs = np.array([ref.torques(*s) for s in zip(qs, qds, qdds)])
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-9)
    for q in qs[:10]:
        np.testing.assert_allclose(dyn.mass_matrix(q), ref.mass_matrix(q), atol=1e-9)


def test_links_on_fixed_joints_are_merged_with_the_same_torques(tmp_path):
    # a CAD export's mounts: a massive link on a fixed joint between b and c (c's joint
    # now hangs from it) and a fixed tool on e; merged into the links they hang from
    mount = """
  <link name="mount">
    <inertial><origin xyz="0.05 -0.03 0.02" rpy="0.2 0.3 -0.1"/><mass value="0.9"/>
      <inertia ixx="0.006" ixy="0.001" ixz="-0.0004" iyy="0.005" iyz="0.0007" izz="0.004"/>
    </inertial>
  </link>
  <link name="tool">
    <inertial><origin xyz="0.0 0.04 0.0" rpy="0 0 0"/><mass value="0.3"/>
      <inertia ixx="0.0007" ixy="0" ixz="0" iyy="0.0005" iyz="0" izz="0.0006"/>
    </inertial>
  </link>
  <joint name="to_mount" type="fixed">
    <parent link="b"/><child link="mount"/><origin xyz="0.15 0.02 -0.05" rpy="0.3 -0.2 0.4"/>
  </joint>
  <joint name="to_tool" type="fixed">
    <parent link="e"/><child link="tool"/><origin xyz="0.0 0.1 0.02" rpy="0 0.6 0"/>
  </joint>
</robot>"""
    text = textwrap.dedent(_URDF).replace("</robot>", mount).replace(
        '<parent link="b"/><child link="c"/>', '<parent link="mount"/><child link="c"/>')
    path = tmp_path / "mounts.urdf"
    path.write_text(text)
    robot = load_description(path).robot
    dyn = InverseDynamics(robot)
    assert len(dyn._model[0]) == len(dyn.kinematics.link_names) - 1 - 2  # two merged
    ref = MujocoReference(robot, dyn)
    qs, qds, qdds = random_states(np.random.default_rng(6), 4, 100)
    ours = dyn.torques_batch(qs, qds, qdds)
    theirs = np.array([ref.torques(*s) for s in zip(qs, qds, qdds)])
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-9)
