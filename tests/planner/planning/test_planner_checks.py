"""src/arduinobot/planner/checks.py: one position-limit check with one tolerance, one joint-name check,
one goal-type check; every layer refuses the same value alike."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.contract.errors import GoalOutOfReach, InvalidRequest, JointLimitViolation
from arduinobot.description import load_description
from arduinobot.planner.checks import LIMIT_TOL, check_joint_names, check_positions, joint_values
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.ik import position_ik
from arduinobot.planner.planning.goal_states import resolve_goal
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.planner.planning.pathfinding.paths import PathRequest


@pytest.fixture(scope="module")
def env():
    d = load_description()
    return d, CollisionWorld(d)


def _layers(env, name: str, value: float) -> dict[str, object]:
    """Hand ``{name: value}`` to every layer that checks position limits; each layer's
    outcome: None if it accepted the value, else the exception."""
    d, w = env
    names = w.kin.joint_names
    q = np.zeros(len(names))
    q[names.index(name)] = value
    out: dict[str, object] = {}

    def run(label, fn):
        try:
            fn()
            out[label] = None
        except JointLimitViolation as e:
            out[label] = e
        except GoalOutOfReach:  # past the limit check: only reaching the target failed
            out[label] = None
    run("service", lambda: joint_values(d, {name: value}, field="start"))
    run("goal", lambda: resolve_goal(JointGoal({name: value}), world=w, description=d,
                                     start=np.zeros(len(names)), group_joints=names))
    # IK keeps a joint it does not solve for at its q_fixed value: it must be in limits
    others = tuple(n for n in ("joint_1", "joint_2", "joint_3") if n != name)
    run("ik", lambda: position_ik(Kinematics(d.robot), d.tcp, (0.0, 0.2, 0.3),
                                  joints=others, q_fixed=q))
    return out


@pytest.mark.parametrize("name", ["joint_1", "joint_3"])
def test_every_layer_shares_one_tolerance(env, name) -> None:
    d, _ = env
    (lo, hi), = d.robot.position_limits((name,))
    inside = _layers(env, name, float(hi) + 0.5 * LIMIT_TOL)
    assert all(v is None for v in inside.values()), inside
    outside = _layers(env, name, float(hi) + 2 * LIMIT_TOL)
    assert all(isinstance(v, JointLimitViolation) for v in outside.values()), outside
    assert {e.joint for e in outside.values()} == {name}  # type: ignore[union-attr]
    assert outside["service"].field == f"start.{name}"  # type: ignore[union-attr]
    assert outside["goal"].field == f"goal.values.{name}"  # type: ignore[union-attr]
    assert outside["ik"].field == f"q_fixed.{name}"  # type: ignore[union-attr]


def test_check_positions_names_the_first_joint_out() -> None:
    lim = np.array([[-1.0, 1.0], [-1.0, 1.0]])
    check_positions(("a", "b"), (1.0 + LIMIT_TOL, -1.0), lim, field="f")
    with pytest.raises(JointLimitViolation) as e:
        check_positions(("a", "b"), (0.0, -1.5), lim, field="f")
    assert e.value.field == "f.b" and e.value.value == -1.5


def test_mimic_and_unknown_joints_are_refused_alike(env) -> None:
    d, w = env
    mimic = d.robot.mimic_joints[0]
    with pytest.raises(InvalidRequest) as svc:
        joint_values(d, {mimic: 0.1}, field="goal.joints")
    with pytest.raises(InvalidRequest) as goal:
        resolve_goal(JointGoal({mimic: 0.1}, where="goal.joints"), world=w, description=d,
                     start=np.zeros(len(w.kin.joint_names)), group_joints=w.kin.joint_names)
    assert svc.value.message == goal.value.message
    assert svc.value.details["leader"] == d.robot.joints[mimic].mimic.joint
    with pytest.raises(InvalidRequest) as e:
        check_joint_names(d, ["wrist"], field="start")
    assert e.value.field == "start.wrist"
    assert e.value.details["actuated"] == list(d.robot.actuated_joints)


def test_goal_type_is_checked_when_a_request_is_built() -> None:
    for build in (lambda g: MotionRequest(goal=g),
                  lambda g: PathRequest(start=np.zeros(4), goal=g)):
        with pytest.raises(InvalidRequest) as e:
            build({"joints": {"joint_1": 0.1}})
        assert e.value.field == "goal" and "unknown goal type dict" in e.value.message
