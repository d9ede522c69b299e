"""A typo in a task file is reported before any step is planned (issue 38, item 6):
the user's flow is `arduinobot task FILE`, whose steps go to plan_task."""

from __future__ import annotations

import pytest
import yaml

from arduinobot.description import load_description
from arduinobot.planner.tasks import TaskStepFailed, plan_task, task_from_mapping

TASK = """
steps:
  - move: {joints: {joint_1: 0.3, joint_2: 0.2, joint_3: -0.2}}
  - move: {joints: {joint_1: -0.3, joint_2: 0.1, joint_3: -0.1}}
  - gripper: open
  - move: {named: %s}
"""


@pytest.fixture(scope="module")
def planner():
    from arduinobot.planner.planning.pipeline import MotionPlanner
    return MotionPlanner(load_description(env={}))


@pytest.mark.parametrize("typo,field,words", [
    ("TASK_NAMED", "steps[3].move.named", "no named state 'hoem'"),
    ("TASK_JOINT", "steps[1].move.joints", "joint_33"),
    ("TASK_GRIPPER", "steps[2].gripper", "'opne' is no state"),
    ("TASK_ATTACH", "steps[2].attach", "no obstacle 'cube'"),
])
def test_a_typo_in_any_step_is_refused_before_the_first_is_planned(planner, typo, field,
                                                                     words):
    text = TASK % "hoem"
    if typo == "TASK_JOINT":
        text = (TASK % "home").replace("joint_3: -0.1", "joint_33: -0.1")
    elif typo == "TASK_GRIPPER":
        text = (TASK % "home").replace("gripper: open", "gripper: opne")
    elif typo == "TASK_ATTACH":
        text = (TASK % "home").replace("gripper: open", "attach: cube")
    task = task_from_mapping(yaml.safe_load(text), name="typo")
    with pytest.raises(TaskStepFailed) as e:
        plan_task(planner, task)
    assert e.value.error.field == field, e.value.error
    assert words in e.value.message, e.value.message
    assert e.value.details["planned_steps"] == 0  # nothing planned before the refusal


def test_a_task_without_typos_still_plans_every_step(planner):
    task = task_from_mapping(yaml.safe_load(TASK % "home"), name="fine")
    result = plan_task(planner, task)
    assert [s.kind for s in result.steps] == ["move", "move", "gripper", "move"]


def test_a_mistyped_step_kind_gets_a_suggestion():
    from arduinobot.contract.errors import InvalidRequest
    with pytest.raises(InvalidRequest) as e:
        task_from_mapping(yaml.safe_load("steps:\n  - mvoe: {named: home}\n"), name="t")
    assert e.value.field == "steps[0]"
    assert "'mvoe' (did you mean 'move'?)" in e.value.message, e.value.message


def test_a_step_naming_what_is_not_there_names_what_is():
    """Pick, place, attach and detach share one lookup: the refusal names the field, the
    id asked for and the ids there are (or 'none' / 'nothing')."""
    from arduinobot.contract.errors import InvalidRequest
    from arduinobot.planner.tasks.progress import Progress
    from arduinobot.scene.obstacles import Obstacle
    box = Obstacle("box", "box", size=[0.1] * 3, xyz=[1.0, 0.0, 0.0])
    p = Progress(None, None, None, {}, [box])  # type: ignore[arg-type]
    assert p.obstacle_index("box", to="pick", field="steps[0].pick") == 0
    with pytest.raises(InvalidRequest) as e:
        p.obstacle_index("cup", to="pick", field="steps[0].pick")
    assert e.value.field == "steps[0].pick"
    assert "no obstacle 'cup' in the scene to pick (obstacles: box)" in e.value.message
    with pytest.raises(InvalidRequest) as e:
        p.carried_index("box", to="place", field="steps[1].place")
    assert e.value.field == "steps[1].place"
    assert "carries no 'box' to place (carried: nothing)" in e.value.message
