import numpy as np
import pytest

from description import load_description
from planner.collision.world import CollisionWorld
from planner.errors import GoalInCollision, GoalOutOfReach, InvalidRequest, JointLimitViolation
from planner.planning.goals import JointGoal, NamedGoal, PositionGoal, resolve_goal


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
    from planner.planning.goals import resolve_group
    desc = env[0]
    assert resolve_group(desc, None, NamedGoal("gripper_open")) == "gripper"
    assert resolve_group(desc, None, JointGoal({"joint_1": 0.1})) == "arm"
    assert resolve_group(desc, "all", NamedGoal("home")) == "all"
    with pytest.raises(InvalidRequest, match="'legs' is not a group of this robot "
                       r"\(groups: arm, gripper, all\)") as e:
        resolve_group(desc, "legs", NamedGoal("home"))
    assert e.value.field == "group"
