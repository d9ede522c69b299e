"""A task's attach takes an object only within reach of what would hold it (issue 38,
item 9: ``attach`` took a box half a metre below the gripper without a word): the pick
of docs/tasks.md with its old approach height is refused at the attach step, naming the
object and the distance."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.tasks import TaskStepFailed, plan_task, task_from_mapping
from arduinobot.scene.frames import MAX_GRASP_DISTANCE
from tests.helpers.pick_place import docs_pick


@pytest.fixture(scope="module")
def planner():
    from arduinobot.planner.planning.pipeline import MotionPlanner
    return MotionPlanner(load_description())


def test_an_attach_far_from_the_gripper_is_refused_naming_object_and_distance(planner):
    task = docs_pick()
    move = next(s for s in task["steps"] if "move" in s)
    move["move"]["position"][2] += 0.56  # where the docs' pick used to close the gripper
    with pytest.raises(TaskStepFailed) as e:
        plan_task(planner, task_from_mapping(task))
    err = e.value.error
    assert e.value.index == 3 and e.value.step.kind == "attach"
    assert err.code == "INVALID_REQUEST" and err.field == "steps[3].attach"
    assert err.details["object"] == "box" and err.details["max_distance"] == MAX_GRASP_DISTANCE
    # the nearest holder (a finger) is half a metre above the box's top
    assert 0.4 < err.details["distance"] < 0.6, err.details
    assert "'box' is" in err.message and f"{err.details['distance']:.3f} m" in err.message
    assert len(e.value.planned) == 3  # open, above, down: planned before the refusal


def test_an_attach_at_the_gripper_takes_the_object(planner):
    result = plan_task(planner, task_from_mapping(docs_pick()))
    attach = next(s for s in result.steps if s.kind == "attach")
    assert attach.object == "box" and attach.link == "claw_support"
    assert result.steps[-1].carried == ("box",)
    ends = [np.array(list(s.end.values())) for s in result.steps]
    assert np.all(np.isfinite(ends))


def test_a_step_s_reach_allows_more_within_its_bound(planner):
    from arduinobot.contract.errors import InvalidRequest
    from arduinobot.planner.tasks.steps import MAX_REACH
    task = docs_pick()
    attach = next(s for s in task["steps"] if "attach" in s)
    attach["reach"] = MAX_REACH + 0.5
    with pytest.raises(InvalidRequest) as e:
        task_from_mapping(task)
    assert e.value.field == "steps[3].reach" and e.value.details["limit"] == MAX_REACH
    attach["reach"] = 0.7  # the far grip above, said to be known
    next(s for s in task["steps"] if "move" in s)["move"]["position"][2] += 0.56
    result = plan_task(planner, task_from_mapping(task))
    assert result.steps[3].kind == "attach" and result.steps[-1].carried == ("box",)
