"""Every mass and wait of a task bounded as the schemas bound them (issue 39, item 8): an
attach mass past plan_request.json's attached mass (1000 kg) is refused naming the field
and the bound, where 1e3-1e308 kg once reached the planner (a NaN effort at 1e308)."""

from __future__ import annotations

import pytest

from arduinobot.contract import wire
from arduinobot.contract.errors import InvalidRequest
from arduinobot.planner.tasks import task_from_mapping
from arduinobot.planner.tasks.steps import MAX_MASS, MAX_WAIT


def _attach(mass: object) -> dict:
    return {"obstacles": [{"id": "box", "shape": "box", "size": [0.05, 0.05, 0.05]}],
            "steps": [{"attach": "box", "mass": mass}]}


def test_the_task_bounds_are_the_schemas() -> None:
    attached = wire.schema("plan_request")["properties"]["attached"]["items"]
    assert attached["properties"]["mass"]["maximum"] == MAX_MASS
    assert MAX_WAIT == 60.0  # docs/tasks.md: "at most 60"


@pytest.mark.parametrize("mass", [1000.5, 1e20, 1e100, 1e308])
def test_an_attach_mass_past_the_bound_is_refused_naming_it(mass: float) -> None:
    with pytest.raises(InvalidRequest) as e:
        task_from_mapping(_attach(mass), where="task")
    assert e.value.field == "task.steps[0].mass"
    assert e.value.details["limit"] == MAX_MASS and "[kg]" in e.value.message


def test_an_attach_mass_at_the_bound_is_taken() -> None:
    step = task_from_mapping(_attach(MAX_MASS)).steps[0]
    assert step.kind == "attach" and step.mass == MAX_MASS  # type: ignore[union-attr]


@pytest.mark.parametrize(("wait", "limit"), [(60.5, MAX_WAIT), (1e308, MAX_WAIT), (-1, 0.0)])
def test_a_wait_out_of_bounds_is_refused_naming_the_bound(wait: float, limit: float) -> None:
    with pytest.raises(InvalidRequest) as e:
        task_from_mapping({"steps": [{"wait": 1}, {"wait": wait}]})
    assert e.value.field == "steps[1].wait" and e.value.details["limit"] == limit
