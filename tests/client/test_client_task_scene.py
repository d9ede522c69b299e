"""PlannerClient.task, .scene and .apply, and the one stream follower behind them, the
CLI's `task --remote` and the ROS 2 task server (client.named_task), through a real
`arduinobot serve` of the shipped arm (its tasks.yaml: 0 wake, 1 pick, 2 sleep; its
robot the MuJoCo twin)."""

from __future__ import annotations

import threading

import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.client.named_task import run_named_task
from arduinobot.client.stream import ExecutionEvent
from tests.helpers.serve import start_server

pytestmark = pytest.mark.slow  # every test here talks to a serve process

#: a long, slow move (several seconds) from where the robot is: time to cancel it mid-way
SLOW = {"steps": [{"move": {"joints": {"joint_1": -1.5, "joint_2": 0.0, "joint_3": -0.9}},
                   "velocity_scaling": 0.03, "acceleration_scaling": 0.03}],
        "seed": 3}


@pytest.fixture(scope="module")
def svc():
    srv = start_server(["--workers", "1"], timeout=240)
    yield srv
    srv.stop()


@pytest.fixture
def c(svc):
    with PlannerClient(svc.endpoint, timeout=60) as client:
        yield client


def test_a_named_task_is_planned_without_moving(c):
    planned: list[object] = []
    r = c.task("pick", trajectories=False, on_planned=planned.append)
    assert r.name == "pick" and [s["kind"] for s in r.steps] == ["move", "gripper"]
    assert r.duration == pytest.approx(sum(s["duration"] for s in r.steps)) and r.duration > 0
    assert all("plan" not in s for s in r.steps)
    assert r.report is None and r.execution is None and planned == [r.planned]
    assert c.task(1).name == "pick"  # by number; with each step's plan this time
    assert "plan" in c.task(1).steps[0]


def test_an_unknown_task_is_refused_naming_its_field(c):
    with pytest.raises(errors.InvalidRequest) as e:
        c.task("no_such_task")
    assert e.value.details["field"] == "name" and "pick" in e.value.details["known"]
    with pytest.raises(TypeError):
        c.task(True)


def test_a_task_runs_on_the_services_robot_with_its_events_in_order(c):
    events: list[ExecutionEvent] = []
    order: list[str] = []
    r = c.task(0, execute=True, move_to_start=True,
               on_planned=lambda b: order.append("planned"),
               on_event=lambda ev: (events.append(ev), order.append(ev.event)))
    assert order[0] == "planned" and order[1] == "started" and order[-1] == "finished"
    assert r.report is not None and r.report["outcome"] == "completed"
    assert r.execution == events[0].execution and events[0].duration == pytest.approx(
        r.duration, abs=0.05)


def test_a_task_is_cancelled_mid_motion_through_the_follower(c):
    cancel = threading.Event()

    def on_event(ev: ExecutionEvent) -> None:
        if ev.event == "progress" and ev.time is not None and ev.time >= 0.5:
            cancel.set()
    r = c.task(SLOW, execute=True, trajectories=False,
               on_event=on_event, cancel=cancel)
    assert r.duration > 3.0  # the move is long enough to be cut
    assert r.report is not None and r.report["outcome"] == "cancelled"
    assert 0.5 <= r.report["cancelled_at"] < r.duration - 1.0


def test_the_ros2_task_servers_runner_reports_progress_to_completion(c):
    fractions: list[float] = []
    done = run_named_task(c.session, c.prefix, 2, on_progress=fractions.append,
                          cancel=threading.Event())
    assert done and fractions[0] == 0.0 and fractions[-1] == 1.0
    assert fractions == sorted(fractions)
    # a refusal is logged and answers False, as the action reports an abort
    assert not run_named_task(c.session, c.prefix, 99, on_progress=fractions.append,
                              cancel=threading.Event())


def test_the_kept_scene_is_read_and_changed_with_if_revision(c):
    before = c.scene()
    box = {"id": "client_box", "shape": "box", "size": [0.1, 0.1, 0.1],
           "xyz": [0.5, 0.5, 0.05], "rpy": [0, 0, 0]}
    applied = c.apply(add=[box], if_revision=before.revision)
    assert applied.revision == before.revision + 1
    assert applied.objects == len(before.objects) + 1
    now = c.scene()
    assert now.revision == applied.revision
    assert [o for o in now.objects if o["id"] == "client_box"][0]["size"] == [0.1, 0.1, 0.1]
    with pytest.raises(errors.SceneConflict) as e:  # the scene moved on: nothing changes
        c.apply(remove=["client_box"], if_revision=before.revision)
    assert e.value.details["current_revision"] == applied.revision
    with pytest.raises(errors.InvalidRequest) as bad:
        c.apply(remove=["not_there"])
    assert bad.value.details["field"].startswith("remove")
    gone = c.apply({"remove": ["client_box"]})
    assert gone.revision == applied.revision + 1 and c.scene().revision == gone.revision


def test_a_task_names_the_scene_revision_it_was_planned_in_and_can_pin_one(c):
    now = c.scene().revision
    planned = c.task(1)  # the course's pick: planned only
    assert planned.scene_revision == now
    assert c.task(1, scene_revision=now).scene_revision == now
    pole = {"id": "task_pin_pole", "shape": "cylinder", "radius": 0.02, "length": 0.2,
            "xyz": [-1.5, -1.5, 0.1]}
    moved = c.apply(add=[pole], if_revision=now)
    try:
        with pytest.raises(errors.SceneConflict) as e:  # the scene moved on: not planned
            c.task(1, scene_revision=now)
        assert e.value.details["current_revision"] == moved.revision
        assert e.value.details["field"] == "scene_revision"
        assert c.task(1).scene_revision == moved.revision
    finally:
        c.apply(remove=["task_pin_pole"])
