import numpy as np
import pytest

from arduinobot.contract.errors import (
    GoalInCollision,
    GoalOutOfReach,
    InvalidRequest,
    JointLimitViolation,
)
from arduinobot.description import load_description
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.planning.goal_states import resolve_goal
from arduinobot.planner.planning.goals import JointGoal, NamedGoal, PositionGoal


@pytest.fixture(scope="module")
def env():
    d = load_description()
    return d, CollisionWorld(d)


def _resolve(env, goal, group=("joint_1", "joint_2", "joint_3")):
    d, w = env
    return resolve_goal(goal, world=w, description=d, start=np.zeros(4), group_joints=group)


def test_joint_and_named(env):
    q = _resolve(env, NamedGoal("reach_left"))
    assert np.allclose(q[0], [1.2, 0.5, 0.9, 0.0])
    assert np.allclose(_resolve(env, JointGoal({"joint_2": 0.3}))[0], [0, 0.3, 0, 0])


def test_errors(env):
    with pytest.raises(JointLimitViolation) as e:
        _resolve(env, JointGoal({"joint_2": 3.0}))
    assert e.value.joint == "joint_2"
    with pytest.raises(InvalidRequest):
        _resolve(env, JointGoal({"joint_4": -0.5}))
    with pytest.raises(InvalidRequest):
        _resolve(env, NamedGoal("nope"))
    with pytest.raises(GoalInCollision) as e:
        _resolve(env, JointGoal({"joint_2": -1.5, "joint_3": -1.0}))
    assert e.value.pairs
    with pytest.raises(GoalOutOfReach):
        _resolve(env, PositionGoal((5.0, 0.0, 0.0)))


def test_position_goal_gives_collision_free_ik(env):
    d, w = env
    tcp = w.kin.point_position(np.array([0.3, 0.5, 0.6, 0.0]), d.tcp.parent_link, d.tcp.xyz)
    qs = _resolve(env, PositionGoal(tuple(tcp)))
    assert len(qs) >= 1
    for q in qs:
        assert w.is_valid(q)
        assert np.linalg.norm(w.kin.point_position(q, d.tcp.parent_link, d.tcp.xyz) - tcp) < 1e-6


def test_groups_come_from_the_robot(env):
    from arduinobot.planner.planning.goal_states import resolve_group
    desc = env[0]
    assert resolve_group(desc, None, NamedGoal("gripper_open")) == "gripper"
    assert resolve_group(desc, None, JointGoal({"joint_1": 0.1})) == "arm"
    assert resolve_group(desc, "all", NamedGoal("home")) == "all"
    with pytest.raises(InvalidRequest, match="'legs' is not a group of this robot "
                       r"\(groups: arm, gripper, all\)") as e:
        resolve_group(desc, "legs", NamedGoal("home"))
    assert e.value.field == "group"


# -- goals with tolerances, honest pose goals ----------------------------------------------

ARM = ("joint_1", "joint_2", "joint_3")


def _edge_of_reach(env, direction):
    """A point 5 mm beyond the workspace's edge along ``direction`` from the shoulder."""
    from arduinobot.planner.kinematics.ik import position_ik

    d, w = env
    shoulder = w.kin.link_pose(np.zeros(4), "forward_drive_arm")[:3, 3]
    u = np.asarray(direction, float) / np.linalg.norm(direction)
    lo, hi = 0.1, 5.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        try:
            position_ik(w.kin, d.tcp, shoulder + mid * u, joints=ARM)
            lo = mid
        except GoalOutOfReach:
            hi = mid
    return shoulder + (lo + 0.005) * u


def test_position_tolerance_reaches_inside_the_sphere(env):
    d, w = env
    goal = tuple(_edge_of_reach(env, (0.3, 1.0, 0.4)))
    with pytest.raises(GoalOutOfReach):
        _resolve(env, PositionGoal(goal))
    qs = _resolve(env, PositionGoal(goal, tolerance=0.01))
    tcp = [w.kin.point_position(q, d.tcp.parent_link, d.tcp.xyz) for q in qs]
    dist = np.linalg.norm(np.array(tcp) - goal, axis=1)
    assert np.all(dist <= 0.01 + 1e-9) and np.all(dist > 0.004)
    assert np.all(np.diff(dist) >= -1e-12)  # nearest the exact goal first


def test_position_tolerance_through_the_planner(env):
    from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest

    d, _ = env
    goal = tuple(_edge_of_reach(env, (0.3, 1.0, 0.4)))
    res = MotionPlanner(d).solve(MotionRequest(goal=PositionGoal(goal, tolerance=0.01),
                                               seed=1))
    r = res.reached
    assert r.within_tolerance and 0.004 < r.position_error <= 0.01
    assert np.linalg.norm(np.array(r.position) - goal) == pytest.approx(r.position_error)


def test_joint_tolerances_take_a_free_state_nearby(env):
    d, w = env
    exact = {"joint_2": -1.2, "joint_3": -0.6}  # the claw just touches the base
    with pytest.raises(GoalInCollision):
        _resolve(env, JointGoal(exact))
    qs = _resolve(env, JointGoal(exact, tolerances={"joint_2": 0.1, "joint_3": 0.1}))
    for q in qs:
        assert w.check(q).valid
        assert abs(q[1] + 1.2) <= 0.1 + 1e-12 and abs(q[2] + 0.6) <= 0.1 + 1e-12
    # nearest the exact goal first
    d = [float(np.abs(q[1:3] - [-1.2, -0.6]).max()) for q in qs]
    assert d == sorted(d) and d[0] > 0
    # a tolerance too small to leave the collision: the exact goal's error
    with pytest.raises(GoalInCollision):
        _resolve(env, JointGoal({"joint_2": -1.5, "joint_3": -1.0},
                                tolerances={"joint_2": 0.1, "joint_3": 0.1}))
    with pytest.raises(InvalidRequest):
        JointGoal(exact, tolerances={"joint_1": 0.1})  # no goal value to be tolerant about
    with pytest.raises(InvalidRequest):
        JointGoal(exact, tolerances={"joint_2": -0.1})


def test_pose_goal_refused_by_the_position_only_arm_naming_its_axes(env):
    from arduinobot.contract.errors import OrientationNotControllable
    from arduinobot.planner.planning.goals import PoseGoal

    d, w = env
    q = np.array([0.3, 0.4, -0.3, 0.0])
    p = w.kin.point_position(q, d.tcp.parent_link, d.tcp.xyz)
    # the tool pointing straight down: not what this position gives the 3-joint arm
    with pytest.raises(OrientationNotControllable) as e:
        _resolve(env, PoseGoal.from_rpy(tuple(p), (np.pi, 0.0, 0.0)))
    err = e.value
    assert err.code == "ORIENTATION_NOT_CONTROLLABLE"
    axes = {tuple(a["joints"]): a for a in err.details["controllable_axes"]}
    assert set(axes) == {("joint_1",), ("joint_2", "joint_3")}
    assert axes[("joint_1",)]["about"] == "world z"
    # joint_2 and joint_3 turn it about one horizontal axis, perpendicular to the arm plane
    h = np.array(axes[("joint_2", "joint_3")]["direction"])
    assert abs(h[2]) < 1e-9 and abs(abs(h @ [np.cos(0.3), np.sin(0.3), 0.0]) - 1) < 1e-6
    assert err.details["orientation_dof"] == 0
    assert "position-only" in err.message and "joint_1" in err.message
    assert err.details["exceeded_axes"]


def test_pose_goal_the_position_already_gives_is_reached_exactly(env):
    from arduinobot.planner.kinematics.rotations import quaternion_of_matrix
    from arduinobot.planner.planning.goals import PoseGoal

    d, w = env
    q = np.array([0.3, 0.4, -0.3, 0.0])
    t = w.kin.link_pose(q, d.tcp.parent_link)
    p = w.kin.point_position(q, d.tcp.parent_link, d.tcp.xyz)
    qs = _resolve(env, PoseGoal(tuple(p), quaternion_of_matrix(t[:3, :3])))
    assert any(np.allclose(c, q, atol=1e-6) for c in qs)
    # every axis free: any orientation, every IK state of the position
    free = _resolve(env, PoseGoal.from_rpy(tuple(p), (np.pi, 0, 0), free_axes=("x", "y", "z")))
    assert len(free) >= 1


@pytest.fixture(scope="module")
def six(tmp_path_factory):
    from arduinobot.planner.planning.pipeline import MotionPlanner
    from tests.helpers.six_joint import make_six_joint

    urdf = make_six_joint(tmp_path_factory.mktemp("six"))
    return MotionPlanner(load_description(urdf, env={}))


SIX_START = {"j2": 0.5, "j3": 1.0, "j5": 0.8}


def test_pose_goal_reached_within_tolerance_on_a_six_joint_arm(six):
    from arduinobot.planner.kinematics.rotations import quaternion_of_matrix, rotation_error
    from arduinobot.planner.planning.goals import PoseGoal
    from arduinobot.planner.planning.pipeline import MotionRequest
    from tests.helpers.fk import tool_frames

    names = six.joint_names
    target_q = np.array([0.3, 0.6, 0.9, 0.2, 0.7, -0.4])
    p, r = tool_frames(six.description, names, [target_q])
    goal = PoseGoal(tuple(p[0]), quaternion_of_matrix(r[0]),
                    orientation_tolerances=(0.01, 0.01, 0.01))
    res = six.solve(MotionRequest(goal=goal, start=SIX_START, seed=3))
    end_p, end_r = tool_frames(six.description, names, [res.trajectory.positions[-1]])
    assert np.linalg.norm(end_p[0] - p[0]) <= 1e-6
    err = rotation_error(r[0], end_r[0])
    assert np.all(np.abs(err) <= 0.01)
    assert res.reached.within_tolerance
    assert np.allclose(res.reached.orientation_error, err, atol=1e-9)
    assert res.verification.ok and res.verification.certified


def test_free_axis_pose_on_a_six_joint_arm(six):
    from arduinobot.planner.planning.goals import PoseGoal
    from arduinobot.planner.planning.pipeline import MotionRequest
    from tests.helpers.fk import tool_frames

    goal = PoseGoal.from_rpy((0.35, 0.1, 0.3), (np.pi, 0.0, 0.0), free_axes=("z",))
    res = six.solve(MotionRequest(goal=goal, start=SIX_START, seed=1))
    _, r = tool_frames(six.description, six.joint_names, [res.trajectory.positions[-1]])
    assert r[0][:, 2] @ [0, 0, -1] > 1 - 1e-6  # the tool's z points down, its yaw free
    assert res.reached.within_tolerance


def test_a_six_joint_line_holds_the_orientation(six):
    from scipy.spatial.transform import Rotation

    from arduinobot.planner.planning.goals import LineGoal
    from arduinobot.planner.planning.pipeline import MotionRequest
    from tests.helpers.fk import tool_frames

    res = six.solve(MotionRequest(goal=LineGoal(offset=(0.0, 0.1, -0.05)), start=SIX_START))
    _, r = tool_frames(six.description, six.joint_names, res.trajectory.positions)
    turn = Rotation.from_matrix(np.swapaxes(r[:1], 1, 2) @ r).magnitude()
    assert turn.max() <= 1e-3  # MAX_TURN: held to 1 mrad, as the position to 1 mm
    assert res.line.max_deviation <= 1e-3


def test_the_wire_parses_the_new_goals():
    from arduinobot.contract.wire import validate
    from arduinobot.planner.planning.goals import LineGoal, PoseGoal
    from arduinobot.service.plan.plan_io import goal as parse_goal

    d = load_description()

    def parsed(g):
        return parse_goal(d, validate("plan", {"goal": g})["goal"])

    assert parsed({"line": {"offset": [0, 0, -0.05], "frame": "tcp"}}) == \
        LineGoal(offset=(0.0, 0.0, -0.05), frame="tcp")
    assert parsed({"line": {"position": [0, 1, 1]}}) == LineGoal(position=(0.0, 1.0, 1.0))
    assert parsed({"position": [0, 1, 1], "tolerance": 0.01}) == \
        PositionGoal((0.0, 1.0, 1.0), tolerance=0.01)
    pose = parsed({"position": [0, 1, 1], "orientation": {"rpy": [np.pi, 0, 0]},
                   "orientation_tolerances": [0.1, 0.1, 0.2], "free_axes": ["z"]})
    assert isinstance(pose, PoseGoal) and pose.free_axes == ("z",)
    assert np.allclose(pose.orientation, (1.0, 0.0, 0.0, 0.0), atol=1e-12)
    q = parsed({"position": [0, 1, 1], "orientation": {"quaternion": [0, 0, 0, 2]}})
    assert q.orientation == (0.0, 0.0, 0.0, 1.0)
    j = parsed({"joints": {"joint_1": 0.2}, "tolerances": {"joint_1": 0.05}})
    assert j.tolerances == {"joint_1": 0.05}
    for bad in ({"line": {"position": [0, 1, 1], "offset": [0, 0, 1]}},
                {"line": {"offset": [0, 0, 1], "frame": "base"}},
                {"position": [0, 1, 1], "orientation": {"rpy": [0, 0]}},
                {"position": [0, 1, 1], "free_axes": ["w"]},
                {"named": "home", "tolerance": 0.1}):
        with pytest.raises(InvalidRequest):
            validate("plan", {"goal": bad})
