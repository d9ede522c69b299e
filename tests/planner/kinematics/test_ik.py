"""Position IK: closed form on the arduinobot, the numeric fallback on another robot."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from arduinobot.contract.errors import GoalOutOfReach, InvalidRequest, JointLimitViolation
from arduinobot.description import Tcp, load_description
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.ik import IkSolution, position_ik

ARM = ("joint_1", "joint_2", "joint_3")


@pytest.fixture(scope="module")
def bot():
    d = load_description()
    return Kinematics(d.robot), d.tcp


def fk(kin: Kinematics, tcp: Tcp, q: np.ndarray) -> np.ndarray:
    return kin.point_position(q, tcp.parent_link, tcp.xyz)


def in_limits(kin: Kinematics, q: np.ndarray) -> bool:
    lim = kin.robot.position_limits()
    return bool(np.all(q >= lim[:, 0]) and np.all(q <= lim[:, 1]))


def test_round_trip_every_solution_hits_target_and_contains_the_origin(bot):
    kin, tcp = bot
    rng = np.random.default_rng(7)
    for _ in range(300):
        q = np.r_[rng.uniform(-1.55, 1.55, 3), 0.0]
        target = fk(kin, tcp, q)
        sols = position_ik(kin, tcp, target)
        assert sols, q
        for s in sols:
            assert isinstance(s, IkSolution) and s.q.shape == (4,)
            assert np.linalg.norm(fk(kin, tcp, s.q) - target) < 1e-6
            assert in_limits(kin, s.q)
            assert s.q[3] == 0.0
        assert min(np.max(np.abs(s.q - q)) for s in sols) < 1e-6
        assert len({s.branch for s in sols}) == len(sols)


def test_home_pose_is_the_only_solution_front_elbow_up(bot):
    kin, tcp = bot
    sols = position_ik(kin, tcp, fk(kin, tcp, np.zeros(4)))
    assert [s.branch for s in sols] == ["front/elbow_up"]
    np.testing.assert_allclose(sols[0].q, 0.0, atol=1e-12)


def test_four_branches_near_the_base(bot):
    # A point close to the yaw axis, low down: every branch stays within the limits.
    kin, tcp = bot
    q = np.array([0.594, 0.173, -1.438, 0.0])
    sols = position_ik(kin, tcp, fk(kin, tcp, q))
    assert [s.branch for s in sols] == ["front/elbow_up", "front/elbow_down",
                                        "back/elbow_up", "back/elbow_down"]
    # front and back share no yaw angle; each pair shares it
    assert sols[0].q[0] == pytest.approx(sols[1].q[0])
    assert sols[2].q[0] == pytest.approx(sols[3].q[0])
    assert abs(sols[0].q[0] - sols[2].q[0]) > 0.5


def test_two_branches_front_only(bot):
    kin, tcp = bot
    q = np.array([0.198, 0.85, -1.369, 0.0])
    sols = position_ik(kin, tcp, fk(kin, tcp, q))
    assert [s.branch for s in sols] == ["front/elbow_up", "front/elbow_down"]


def test_q_fixed_gives_the_other_joints(bot):
    kin, tcp = bot
    target = fk(kin, tcp, np.array([0.3, 0.2, -0.4, 0.0]))
    sols = position_ik(kin, tcp, target, q_fixed=[0.0, 0.0, 0.0, -0.7])
    assert all(s.q[3] == -0.7 for s in sols)


def test_out_of_workspace(bot):
    kin, tcp = bot
    with pytest.raises(GoalOutOfReach) as e:
        position_ik(kin, tcp, [5.0, 0.0, 0.0])
    assert "out of the workspace" in str(e.value)
    d = e.value.details
    assert d["reason"] == "out_of_workspace"
    assert d["position"] == [5.0, 0.0, 0.0]
    assert 2.0 < d["nearest_distance"] <= d["nearest_distance_within_limits"]
    assert d["reach"]["shoulder_to_tcp_max"] == pytest.approx(0.8 + np.hypot(1.40, 0.155))
    assert d["reach"]["min_distance_from_yaw_axis"] == pytest.approx(0.15)
    assert e.value.code == "GOAL_OUT_OF_REACH"


def test_inside_the_yaw_offset_cylinder_is_out_of_workspace(bot):
    # The arm plane sits 0.15 m off the yaw axis: points on the axis are unreachable.
    kin, tcp = bot
    with pytest.raises(GoalOutOfReach) as e:
        position_ik(kin, tcp, [0.0, 0.0, 1.5])
    assert e.value.details["reason"] == "out_of_workspace"


def test_reachable_only_outside_limits(bot):
    # Straight behind the base: the yaw would have to turn ~pi.
    kin, tcp = bot
    with pytest.raises(GoalOutOfReach) as e:
        position_ik(kin, tcp, [0.0, -1.5, 1.3])
    assert "only outside the joint limits" in str(e.value)
    d = e.value.details
    assert d["reason"] == "outside_joint_limits"
    assert len(d["solutions_outside_limits"]) == 4
    lim = kin.robot.position_limits(ARM)
    for sol in d["solutions_outside_limits"]:
        q = np.array([sol[n] for n in ARM])
        assert np.any((q < lim[:, 0]) | (q > lim[:, 1]))
        assert np.linalg.norm(fk(kin, tcp, np.r_[q, 0.0]) - [0.0, -1.5, 1.3]) < 1e-9
    assert d["nearest_distance_within_limits"] > 0.1


@pytest.mark.parametrize("bad", [[1.0, 2.0], [1.0, np.nan, 0.0], "abc", [[1, 2, 3]],
                                 [1.0, np.inf, 0.0]])
def test_invalid_position(bot, bad):
    kin, tcp = bot
    with pytest.raises(InvalidRequest) as e:
        position_ik(kin, tcp, bad)
    assert e.value.field == "position"


def test_invalid_joints_and_q_fixed(bot):
    kin, tcp = bot
    target = fk(kin, tcp, np.zeros(4))
    with pytest.raises(InvalidRequest) as e:
        position_ik(kin, tcp, target, joints=("joint_1", "joint_9", "joint_3"))
    assert e.value.field == "joints"
    with pytest.raises(InvalidRequest) as e:
        position_ik(kin, tcp, target, joints=("joint_1", "joint_1", "joint_3"))
    assert e.value.field == "joints"
    # joint_4 moves the fingers, not the tcp on claw_support
    with pytest.raises(InvalidRequest, match="does not move the tcp"):
        position_ik(kin, tcp, target, joints=("joint_1", "joint_2", "joint_4"))
    with pytest.raises(InvalidRequest) as e:
        position_ik(kin, tcp, target, q_fixed=[0.0, 0.0])
    assert e.value.field == "q_fixed"
    with pytest.raises(JointLimitViolation):
        position_ik(kin, tcp, target, q_fixed=[0.0, 0.0, 0.0, 0.5])
    with pytest.raises(InvalidRequest) as e:
        position_ik(kin, tcp, target, tolerance=0.0)
    assert e.value.field == "tolerance"


def test_numeric_fallback_agrees_with_closed_form(bot):
    # Listing the joints out of chain order forces the generic solver on the same arm.
    kin, tcp = bot
    rng = np.random.default_rng(3)
    for _ in range(10):
        q = np.r_[rng.uniform(-1.5, 1.5, 3), 0.0]
        target = fk(kin, tcp, q)
        closed = position_ik(kin, tcp, target)
        numeric = position_ik(kin, tcp, target, joints=("joint_3", "joint_1", "joint_2"))
        assert all(s.branch.startswith("solution ") for s in numeric)
        a = sorted(tuple(np.round(s.q, 6)) for s in closed)
        b = sorted(tuple(np.round(s.q, 6)) for s in numeric)
        np.testing.assert_allclose(a, b, atol=1e-5)


def test_deterministic(bot):
    kin, tcp = bot
    target = fk(kin, tcp, np.array([0.594, 0.173, -1.438, 0.0]))
    for joints in (ARM, ("joint_2", "joint_3", "joint_1")):
        a = position_ik(kin, tcp, target, joints=joints)
        b = position_ik(kin, tcp, target, joints=joints)
        assert [s.branch for s in a] == [s.branch for s in b]
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x.q, y.q)


_SKEW_URDF = """\
<?xml version="1.0"?>
<robot name="skew">
  <link name="base"><visual><geometry><box size="0.2 0.2 0.1"/></geometry></visual></link>
  <link name="l1"><collision><geometry><box size="0.1 0.1 0.3"/></geometry></collision></link>
  <link name="l2"><collision><geometry><box size="0.4 0.05 0.05"/></geometry></collision></link>
  <link name="l3"><collision><geometry><box size="0.05 0.3 0.05"/></geometry></collision></link>
  <link name="tool"/>
  <joint name="yaw" type="continuous">
    <parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit effort="5" velocity="2"/>
  </joint>
  <joint name="pitch" type="revolute">
    <parent link="l1"/><child link="l2"/><origin xyz="0.05 0 0.3" rpy="0.3 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2.0" upper="2.0" effort="5" velocity="2"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="l2"/><child link="l3"/><origin xyz="0.4 0 0" rpy="0 0.5 0"/>
    <axis xyz="1 0 0"/><limit lower="0.0" upper="0.3" effort="50" velocity="0.5"/>
  </joint>
  <joint name="tool_fixed" type="fixed">
    <parent link="l3"/><child link="tool"/><origin xyz="0 0.1 0.05"/>
  </joint>
</robot>
"""


@pytest.fixture(scope="module")
def skew(tmp_path_factory):
    path = tmp_path_factory.mktemp("skew") / "skew.urdf"
    path.write_text(textwrap.dedent(_SKEW_URDF))
    d = load_description(path)
    return Kinematics(d.robot), Tcp("tool", (0.02, 0.0, 0.0))


def test_generic_robot_round_trip(skew):
    kin, tcp = skew
    assert kin.joint_names == ("yaw", "pitch", "slide")
    rng = np.random.default_rng(11)
    for _ in range(20):
        q = np.array([rng.uniform(-3, 3), rng.uniform(-1.9, 1.9), rng.uniform(0.01, 0.29)])
        target = fk(kin, tcp, q)
        sols = position_ik(kin, tcp, target, joints=kin.joint_names)
        assert sols
        assert [s.branch for s in sols] == [f"solution {k + 1}" for k in range(len(sols))]
        for s in sols:
            assert np.linalg.norm(fk(kin, tcp, s.q) - target) < 1e-6
            assert -np.pi < s.q[0] <= np.pi  # continuous joint wrapped
            assert -2.0 <= s.q[1] <= 2.0 and 0.0 <= s.q[2] <= 0.3
        d = [np.max(np.abs(np.r_[np.remainder(s.q[0] - q[0] + np.pi, 2 * np.pi) - np.pi,
                                 s.q[1:] - q[1:]])) for s in sols]
        assert min(d) < 1e-6


def test_generic_robot_errors(skew):
    kin, tcp = skew
    with pytest.raises(GoalOutOfReach) as e:
        position_ik(kin, tcp, [3.0, 0.0, 0.0], joints=("yaw", "pitch"),
                    q_fixed=[0.0, 0.0, 0.3])
    assert e.value.details["reason"] == "out_of_workspace"
    assert "reach" not in e.value.details
    assert 1.5 < e.value.details["nearest_distance"] < 3.0
    # An unbounded slide reaches anything: far away counts as outside the limits.
    with pytest.raises(GoalOutOfReach) as e:
        position_ik(kin, tcp, [3.0, 0.0, 0.0], joints=kin.joint_names)
    assert e.value.details["reason"] == "outside_joint_limits"
    assert e.value.details["solutions_outside_limits"][0]["slide"] > 2.0
    # Reachable with the slide extended past its 0.3 m limit.
    target = fk(kin, tcp, np.array([0.4, 0.3, 0.6]))
    with pytest.raises(GoalOutOfReach) as e:
        position_ik(kin, tcp, target, joints=kin.joint_names)
    assert e.value.details["reason"] == "outside_joint_limits"


def test_generic_robot_subset_of_joints(skew):
    # Two joints for three coordinates: only points on their surface are solvable.
    kin, tcp = skew
    q = np.array([0.7, -0.5, 0.2])
    target = fk(kin, tcp, q)
    sols = position_ik(kin, tcp, target, joints=("yaw", "pitch"), q_fixed=[0.0, 0.0, 0.2])
    assert any(np.allclose(s.q, q, atol=1e-6) for s in sols)
    assert all(s.q[2] == 0.2 for s in sols)


def test_branch_labels_mean_what_they_say(bot):
    # front: the tcp lies ahead of the turntable (its +y); elbow_up: the elbow lies
    # above the shoulder-tcp line, seen in the arm's plane.
    kin, tcp = bot
    rng = np.random.default_rng(13)
    seen = set()
    for _ in range(200):
        q = np.r_[rng.uniform(-1.55, 1.55, 3), 0.0]
        target = fk(kin, tcp, q)
        for s in position_ik(kin, tcp, target):
            poses = kin.link_poses(s.q)
            plate = poses[kin.link_index["base_plate"]]
            shoulder = poses[kin.link_index["forward_drive_arm"]][:3, 3]
            elbow = poses[kin.link_index["horizontal_arm"]][:3, 3]
            ahead = plate[:3, 1] @ (target - plate[:3, 3])
            side, elbow_label = s.branch.split("/")
            assert (ahead >= 0) == (side == "front"), (s.branch, ahead)
            plane = np.eye(3) - np.outer(plate[:3, 0], plate[:3, 0])  # the arm's plane
            d, e = plane @ (target - shoulder), plane @ (elbow - shoulder)
            up = np.array([0, 0, 1.0])
            normal = up * (d @ d) - (up @ d) * d  # the line's normal pointing up
            above = normal @ e >= 0
            assert above == (elbow_label == "elbow_up"), s.branch
            seen.add(s.branch)
    assert seen == {"front/elbow_up", "front/elbow_down", "back/elbow_up", "back/elbow_down"}
