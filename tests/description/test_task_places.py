"""Issue 42, item 5: a tasks.yaml names places (a position, an obstacle to put things on,
or an obstacle's id), every task of the file has them, and a task's own add to them."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from arduinobot.description.errors import DescriptionError
from arduinobot.description.moveit_config import read_tasks
from arduinobot.planner.tasks import PlaceTarget, task_from_mapping


def test_a_tasks_file_s_places_are_every_task_s(tmp_path: Path) -> None:
    f = tmp_path / "tasks.yaml"
    f.write_text(yaml.safe_dump({
        "places": {"bin": {"position": [-0.55, 0.78, 0.4]}, "shelf": "top_board",
                   "tray": {"on": "tray_floor"}},
        "tasks": {"put_away": {"number": 3, "steps": [{"pick": "box"},
                                                      {"place": "box", "at": "bin"}]},
                  "mine": {"places": {"bin": {"position": [0, 0.5, 0.3]}},
                           "steps": [{"pick": "box"}, {"place": "box", "at": "tray"}]}}}))
    tasks = read_tasks(f)
    put = task_from_mapping(tasks["put_away"].body, name="put_away")
    assert put.places["bin"] == PlaceTarget(position=(-0.55, 0.78, 0.4))
    # a name alone is an obstacle to put things on
    assert put.places["shelf"] == PlaceTarget(on="top_board")
    assert put.places["tray"] == PlaceTarget(on="tray_floor")
    assert put.steps[1].at == PlaceTarget(name="bin")  # type: ignore[union-attr]
    mine = task_from_mapping(tasks["mine"].body, name="mine")
    assert mine.places["bin"].position == (0.0, 0.5, 0.3)  # the task's own wins
    assert set(mine.places) == {"bin", "shelf", "tray"}


def test_bad_places_are_refused_naming_the_field(tmp_path: Path) -> None:
    f = tmp_path / "tasks.yaml"
    f.write_text(yaml.safe_dump({"places": ["bin"], "tasks": {"t": [{"wait": 1}]}}))
    with pytest.raises(DescriptionError) as e:
        read_tasks(f)
    assert "places" in str(e.value)
    from arduinobot.contract.errors import InvalidRequest
    with pytest.raises(InvalidRequest) as e2:
        task_from_mapping({"places": {"bin": {"position": [1, 2]}}, "steps": [{"wait": 1}]},
                          where="tasks.t")
    assert e2.value.field == "tasks.t.places.bin.position"
