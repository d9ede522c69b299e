"""The ground (issue 38, item 5): the plane the base stands on is an obstacle by default,
so a straight line cannot end under it; a request opts out with ``"ground": false``.

Typed as the SO-101's owner did (tests/helpers/so101.py, the folder as published): a LIN
to 1.5 cm under the plane the base stands on, which planned before. Every request that
builds a world has it the same way: plan, check (padded, carrying), a moving start (a
blend's plan), a task, a plan in the kept scene; an obstacle of the user's own named
``ground`` replaces ours."""

from __future__ import annotations

import json

import pytest

from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.description import load_description
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.planner.tasks import TaskStepFailed, plan_task, task_from_mapping
from arduinobot.scene.ground import GROUND_ID, ground_obstacle, with_ground
from arduinobot.scene.obstacles import Obstacle
from arduinobot.service.local import LocalService, load_scene
from tests.helpers.so101 import make_so101

UNDER = {"line": {"position": [0.2, 0.0, -0.015]}}  # 1.5 cm under the plane [m]
#: a ground of the user's own, far from the arm: it replaces ours
FAR_GROUND = {"id": "ground", "shape": "box", "size": [0.1, 0.1, 0.1], "xyz": [3.0, 3.0, -1.0]}


@pytest.fixture(scope="module")
def desc(tmp_path_factory):
    return load_description(make_so101(tmp_path_factory.mktemp("so101")), env={})


@pytest.fixture(scope="module")
def svc(desc):
    return LocalService(desc)


@pytest.fixture(scope="module")
def under(svc):
    """The state [rad] the LIN ends in without the ground: the tool 1.5 cm under it."""
    reply = svc.request("plan", {"goal": UNDER, "seed": 1, "ground": False})
    assert reply["verification"]["ok"], reply["verification"]
    names = reply["trajectory"]["joint_names"]
    return dict(zip(names, reply["trajectory"]["points"][-1]["positions"]))


def _names_ground(pairs) -> bool:
    return any(GROUND_ID in p for p in pairs)


def test_a_line_below_the_ground_is_refused_naming_the_ground(svc):
    with pytest.raises(PlanningError) as e:
        svc.request("plan", {"goal": UNDER, "seed": 1})
    assert e.value.code == "LINE_INTERRUPTED", e.value
    assert _names_ground(e.value.details["pairs"]), e.value.details
    # it stops where the tool meets the plane, not at the start: the arm's own base
    # stands on the ground without colliding
    assert 0.5 < e.value.details["fraction"] < 1.0, e.value.details


def test_home_and_a_plan_above_the_ground_still_plan(svc):
    reply = svc.request("plan", {"goal": {"line": {"position": [0.2, 0.0, 0.05]}}, "seed": 1})
    assert reply["verification"]["ok"], reply["verification"]


def test_ground_false_opts_out(svc, under):
    # the fixture planned it: its last state has the tool under the plane
    reply = svc.request("fk", {"joints": under})
    assert reply["tcp"][2] == pytest.approx(-0.015, abs=2e-3), reply["tcp"]


def test_check_has_the_ground_padded_or_carrying(svc, under):
    res = svc.request("check", {"joints": under})
    assert not res["valid"] and _names_ground(res["pairs"]), res
    assert svc.request("check", {"joints": under, "ground": False})["valid"]
    # a padded world pads the ground too
    res = svc.request("check", {"joints": under, "padding": 0.005})
    assert not res["valid"] and _names_ground(res["pairs"]), res
    # carrying: the world with the carried object keeps the ground
    pen = {"object": {"id": "pen", "shape": "sphere", "radius": 0.004, "xyz": [0, 0, 0]},
           "link": "gripper_link"}
    res = svc.request("check", {"joints": under, "attached": [pen]})
    assert not res["valid"] and _names_ground(res["pairs"]), res
    assert "pen" in res["carried"]
    # at home nothing touches it: the base stands on it
    assert svc.request("check", {"joints": {}})["valid"]


def test_an_obstacle_of_ones_own_named_ground_replaces_ours(svc, under):
    res = svc.request("check", {"joints": under, "obstacles": [FAR_GROUND]})
    assert res["valid"], res
    own = Obstacle.from_mapping(FAR_GROUND, where="obstacles[0]")
    assert with_ground((own,)) == (own,)
    assert with_ground(()) == (ground_obstacle(),)
    assert with_ground((), False) == ()


def test_the_kept_scene_keeps_the_ground_or_replaces_it(svc, desc, under, tmp_path):
    table = {"id": "table", "shape": "box", "size": [0.2, 0.2, 0.02], "xyz": [-0.4, 0.3, 0.1]}
    scenes = {}
    for name, objects in (("table", [table]), ("own", [table, FAR_GROUND])):
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps({"revision": 1, "objects": objects}))
        scenes[name] = load_scene(desc, str(path))
    try:
        svc.scene = scenes["table"]
        res = svc.request("check", {"joints": under})
        assert not res["valid"] and _names_ground(res["pairs"]), res
        with pytest.raises(PlanningError) as e:
            svc.request("plan", {"goal": UNDER, "seed": 1})
        assert _names_ground(e.value.details["pairs"]), e.value.details
        svc.scene = scenes["own"]
        assert svc.request("check", {"joints": under})["valid"]
    finally:
        svc.scene = None


@pytest.fixture(scope="module")
def mp(desc):
    return MotionPlanner(desc)


def test_a_moving_start_plans_on_the_ground(mp, under):
    """A blend's plan (a moving start: a brake, a plan from rest, the two superposed)
    refuses a goal under the plane as a plan from rest does, and plans it without."""
    moving = {"shoulder_pan": 0.2}
    for velocity in (None, moving):
        with pytest.raises(PlanningError) as e:
            mp.solve(MotionRequest(goal=JointGoal(under), group="all", seed=1,
                                   start_velocity=velocity))
        assert e.value.code == "GOAL_IN_COLLISION", e.value
        assert _names_ground(e.value.details["pairs"]), e.value.details
    res = mp.solve(MotionRequest(goal=JointGoal(under), group="all", seed=1,
                                 start_velocity=moving, ground=False))
    assert res.verification.ok, res.verification


def test_a_task_plans_on_the_ground_unless_it_says_ground_false(mp):
    task = {"steps": [{"line": {"position": [0.2, 0.0, 0.05]}}, {"line": UNDER["line"]}],
            "seed": 1}
    with pytest.raises(TaskStepFailed) as e:
        plan_task(mp, task_from_mapping(task))
    assert e.value.index == 1 and e.value.error.code == "LINE_INTERRUPTED", e.value
    assert _names_ground(e.value.error.details["pairs"]), e.value.error.details
    done = plan_task(mp, task_from_mapping({**task, "ground": False}))
    assert len(done.steps) == 2
    with pytest.raises(InvalidRequest) as bad:
        task_from_mapping({**task, "ground": "no"})
    assert bad.value.field == "ground", bad.value
