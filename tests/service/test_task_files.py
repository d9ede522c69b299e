"""A task from the wire names no file of the server (issue 39, item 5): an obstacle's
``mesh_path`` is refused naming the field, before the file is looked at, with the same
words whether the file exists or not (no file-existence oracle); a task of the service's
own tasks.yaml may still name one."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import trimesh

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import load_description
from arduinobot.service.task.task_service import TaskService, answer_task


def _task(path: str) -> dict[str, Any]:
    return {"obstacles": [{"id": "box", "shape": "box", "size": [0.1, 0.1, 0.1],
                           "xyz": [0.3, 0, 0.05]},
                          {"id": "part", "shape": "mesh", "mesh_path": path,
                           "xyz": [0.2, 0.1, 0.05]}],
            "steps": [{"wait": 0.5}]}


def _service(tasks_file: Path | None = None) -> TaskService:
    # job() reads the request alone: no session, no pool
    return TaskService(None, "arduinobot", load_description(),  # type: ignore[arg-type]
                       submit=lambda kind, job, respond: None,
                       tasks_file=tasks_file)


def _refusal(path: str) -> InvalidRequest:
    job = _service().job({"task": _task(path)})
    assert job["files"] is False
    with pytest.raises(InvalidRequest) as e:
        answer_task(None, job, scene=None)  # refused before any planner is asked
    return e.value


def test_a_wire_task_mesh_path_is_refused_the_same_whether_the_file_exists(tmp_path: Path
                                                                           ) -> None:
    there = tmp_path / "part.stl"
    trimesh.creation.box(extents=(0.05, 0.05, 0.05)).export(there)
    missing = tmp_path / "nothing.stl"
    found, absent = _refusal(str(there)), _refusal(str(missing))
    for err in (found, absent):
        assert err.field == "task.obstacles[1].mesh_path"
        assert str(tmp_path) not in err.message  # the path is not echoed
        assert "inline" in err.message
    assert (found.message, found.details) == (absent.message, absent.details)


def test_a_named_task_of_the_service_may_name_a_mesh_file(tmp_path: Path) -> None:
    there = tmp_path / "part.stl"
    trimesh.creation.box(extents=(0.05, 0.05, 0.05)).export(there)
    tasks = tmp_path / "tasks.yaml"
    tasks.write_text("tasks:\n  hold:\n    obstacles:\n"
                     f"      - {{id: part, shape: mesh, mesh_path: '{there}', "
                     "xyz: [0.2, 0.1, 0.05]}\n    steps:\n      - wait: 0.5\n")
    job = _service(tasks).job({"name": "hold"})
    assert job["files"] is True and job["where"] == "tasks.hold"
    from arduinobot.planner.tasks import task_from_mapping
    task = task_from_mapping(job["task"], where=job["where"], files=job["files"])
    assert task.obstacles[0].mesh_path == str(there)


@pytest.mark.slow  # starts serve
def test_through_serve_a_task_mesh_path_is_refused_and_an_attach_mass_bounded(tmp_path: Path
                                                                              ) -> None:
    from tests.helpers.serve import start_server
    from tests.service.test_task_pool import _task_query

    there = tmp_path / "part.stl"
    trimesh.creation.box(extents=(0.05, 0.05, 0.05)).export(there)
    srv = start_server(["--workers", "1", "--no-robot", "--scene-file",
                        str(tmp_path / "scene.json")])
    try:
        answers = {}
        for name, path in (("there", str(there)), ("missing", str(tmp_path / "no.stl"))):
            (reply,) = _task_query(srv.endpoint, {"task": _task(path)})
            answers[name] = reply["error"]
            answers[name]["details"].pop("request_id")  # each request's own
        for err in answers.values():
            assert err["code"] == "INVALID_REQUEST"
            assert err["details"]["field"] == "task.obstacles[1].mesh_path"
            assert str(tmp_path) not in err["message"]
        assert answers["there"] == answers["missing"]  # no file-existence oracle
        heavy = {"obstacles": [{"id": "box", "shape": "box", "size": [0.05, 0.05, 0.05]}],
                 "steps": [{"attach": "box", "mass": 1e308}]}
        (reply,) = _task_query(srv.endpoint, {"task": heavy, "trajectories": False})
        assert reply["error"]["details"]["field"] == "task.steps[0].mass"
        assert reply["error"]["details"]["limit"] == 1000.0
    finally:
        srv.stop()
