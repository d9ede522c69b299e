"""A running task's rest cut by its steps (service/execute/task_react.py) and a stopped
task's rest planned again (service/execute/task_replan.py): which states each piece is
sent, where a refusal falls, and which step a replan resumes at with what it carries."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.service.execute.task_react import TaskPieces
from arduinobot.service.execute.task_replan import resume_job, resumed

BOX = {"id": "box", "shape": "box", "size": [0.08, 0.08, 0.08], "xyz": [0.1, 0.0, 0.0]}
HELD = {"object": BOX, "link": "claw_support", "touch_links": [], "mass": 0.05}
STEPS = [{"pick": "box"}, {"place": "box", "at": "bin"},
         {"line": {"offset": [0.0, 0.0, 0.05]}}]


class Line:
    """A segment moving joint_1 at 1 rad/s for ``duration`` [s]."""

    joint_names = ("joint_1", "joint_2")

    def __init__(self, duration: float) -> None:
        self.duration = duration

    def evaluate(self, t: float):
        return np.array([t, 0.0]), np.array([1.0, 0.0]), np.zeros(2)


def _piece(step, kind, task_step, task_kind, start, end, *, attached=(), allowed=()):
    return {"step": step, "kind": kind, "label": None, "task_step": task_step,
            "task_kind": task_kind, "start": start, "end": end,
            "obstacles": [{"id": "table", "shape": "box", "size": [1, 1, 0.05],
                           "xyz": [0, 0, 0]}],
            "attached": list(attached), "allowed": [list(p) for p in allowed]}


@pytest.fixture
def task() -> TaskPieces:
    return TaskPieces.of({
        "name": "pp", "moved": ["box"], "pieces": [
            _piece(1, "move", 0, "pick", 0.0, 1.0),
            _piece(4, "line", 0, "pick", 1.0, 2.5, attached=[HELD],
                   allowed=[("box", "table")]),
            _piece(5, "move", 1, "place", 2.5, 4.0, attached=[HELD]),
            _piece(8, "line", 1, "place", 4.0, 5.0),
            _piece(9, "line", 2, "line", 5.0, 6.0)],
        "replan": {"task": {"steps": STEPS, "places": {"bin": {"position": [0, 0, 0]}}},
                   "where": "tasks.pp", "name": "pp", "files": True}})


def test_the_rest_is_cut_by_the_steps_and_the_pieces_meet(task):
    data, spans = task.rest(Line(6.0), 0.55, 10.0)
    assert [i for i, _ in spans] == [0, 1, 2, 3, 4]
    first = spans[0][1]
    assert first[0] == pytest.approx(0.55) and first[-1] == pytest.approx(1.0)
    for (_, a), (_, b) in zip(spans, spans[1:]):
        assert a[-1] == pytest.approx(b[0])  # each step ends where the next starts
    sent = data["pieces"]
    assert np.allclose(np.array(sent[1]["positions"])[:, 0], spans[1][1])
    assert sent[1]["attached"] == [HELD] and sent[1]["allowed"] == [["box", "table"]]
    assert sent[0]["attached"] == [] and data["moved"] == ["box"]
    # later: the pieces already played are not sent
    later, spans = task.rest(Line(6.0), 4.2, 10.0)
    assert [i for i, _ in spans] == [3, 4] and len(later["pieces"]) == 2


def test_a_refusal_names_its_step_and_the_last_certified_time(task):
    _, spans = task.rest(Line(6.0), 0.55, 10.0)
    until, refused, step = task.where(
        {"piece": 2, "safe": -1, "refused": {"state": 3, "pair": ["box", "x"]}}, spans)
    assert until == pytest.approx(2.5)  # certified through the piece before it
    assert refused == {"time": pytest.approx(2.8), "pair": ["box", "x"]}
    assert step == {"index": 5, "kind": "move", "label": None, "task_step": 1,
                    "task_kind": "place"}
    until, _, _ = task.where({"piece": 0, "safe": -1,
                              "refused": {"state": 0, "pair": ["a", "b"]}}, spans)
    assert until is None
    until, _, _ = task.where({"piece": 0, "safe": 2,
                              "refused": {"state": 3, "pair": ["a", "b"]}}, spans)
    assert until == pytest.approx(0.75)


def test_a_replan_resumes_at_the_step_it_stopped_in_with_what_it_carries(task):
    state = {"joint_1": 0.4, "joint_2": 0.0}
    job, _ = resume_job(task, 0.4, state, on_change="replan")
    assert job is not None and resumed(job) == {"task_step": 0, "kind": "pick"}
    assert job["task"]["steps"] == STEPS and job["task"]["start"] == state
    assert job["carrying"] == [] and job["exclude"] == ["box"]
    assert job["files"] is False  # it came back on the wire: it names no server file
    assert job["task"]["places"] == {"bin": {"position": [0, 0, 0]}}
    # in the pick's lift, the box held: the pick is done but its lift; the place is next
    job, _ = resume_job(task, 2.0, state, on_change="stop")
    assert job is not None and resumed(job) == {"task_step": 1, "kind": "place"}
    assert job["task"]["steps"] == STEPS[1:] and job["carrying"] == [HELD]
    assert job["resting"] == [["box", "table"]] and job["on_change"] == "stop"
    assert job["source"] == task.replan  # a later stop replans the task as given
    # in the place's move, the box still held: the place again
    job, _ = resume_job(task, 3.0, state, on_change="replan")
    assert job is not None and resumed(job)["task_step"] == 1
    # in the place's retreat, the box let go: the line after it, an offset: refused
    job, why = resume_job(task, 4.5, state, on_change="replan")
    assert job is None and "step 2 is a line given as an offset" in why
    job, why = resume_job(task, 5.5, state, on_change="replan")
    assert job is None and "step 2 is a line given as an offset" in why
    job, why = resume_job(task, 6.0, state, on_change="replan")
    assert job is None and "nothing is left" in why
