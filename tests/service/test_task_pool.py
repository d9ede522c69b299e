"""Tasks in the worker pool: ``<prefix>/task`` plans each task as a ``task`` job, and a
kept-scene attach or detach asks the pool for link poses and contacts (``frames`` jobs),
so the serving process never imports the planner (checked in a real serve's
``sys.modules`` at its exit); a task job's deadline counts every step's planning time; a worker reuses the
kept scene it was sent last instead of receiving it with every job."""

from __future__ import annotations

import os
import signal
import threading
from multiprocessing import Pipe
from pathlib import Path
from typing import Any

import numpy as np
import orjson
import pytest

from arduinobot.client import errors
from arduinobot.contract import wire
from arduinobot.description import load_description
from arduinobot.scene.obstacles import Obstacle
from arduinobot.scene.state import SceneSnapshot
from arduinobot.service.messages import HELD_SCENE, Done, JobMsg, Stop, Success, TakenMark
from arduinobot.service.process.slot import Slot
from arduinobot.service.process.worker import DEFAULT_PLANNING_TIME, job_deadline, serve_jobs
from arduinobot.service.process.zygote import WorkerProcess
from tests.helpers.fk import link_pose
from tests.helpers.serve import start_server

#: what only the planner's processes may import: the planning pipeline, the task
#: planner, the compiled kernels, OMPL, the collision and timing libraries
PLANNER_MODULES = ("arduinobot.planner.planning.pipeline", "arduinobot.planner.tasks", "arduinobot.planner.collision.world",
                   "numba", "ompl", "fcl", "toppra")

#: imported first by every Python process started with this folder on its path: at the
#: process's exit, its modules go to <ARDUINOBOT_TEST_MODULES>/<pid>.txt
_SITECUSTOMIZE = """
import atexit, os, sys

def _modules():
    with open(os.path.join(os.environ["ARDUINOBOT_TEST_MODULES"], f"{os.getpid()}.txt"),
              "w") as f:
        f.write("\\n".join(sorted(sys.modules)))

atexit.register(_modules)
"""


def _task_query(endpoint: str, body: dict[str, Any]) -> list[dict[str, Any]]:
    import zenoh

    from arduinobot.contract.zconfig import zenoh_config
    out = []
    with zenoh.open(zenoh_config(mode="client", connect=[endpoint], listen=[])) as s:
        for r in s.get("arduinobot/task", payload=wire.encode(body),
                       consolidation=zenoh.ConsolidationMode.NONE, timeout=120.0):
            out.append(orjson.loads((r.ok or r.err).payload.to_bytes()))
    return out


@pytest.mark.slow
def test_tasks_and_attaches_go_to_the_pool_and_serve_never_imports_the_planner(
        tmp_path: Path):
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(_SITECUSTOMIZE)
    modules = tmp_path / "modules"
    modules.mkdir()
    env = {**os.environ, "ARDUINOBOT_TEST_MODULES": str(modules),
           "PYTHONPATH": os.pathsep.join([str(hook), os.environ.get("PYTHONPATH", "")])}
    d = load_description()
    link = d.tcp.parent_link
    path = [j.name for j in d.robot.link_path("horizontal_arm")]
    ball_at = link_pose(d.robot, "horizontal_arm", path, np.zeros(len(path)))[:3, 3].tolist()
    srv = start_server(["--workers", "1", "--no-robot"], env=env)
    try:
        from arduinobot.client.client import PlannerClient
        with PlannerClient(srv.endpoint, timeout=60) as c:
            planned = _task_query(srv.endpoint, {"number": 1, "trajectories": False})
            # a step that cannot be planned: its code and step, from the worker
            bad = _task_query(srv.endpoint, {"task": {"steps": [
                {"move": {"joints": {"joint_1": 9.0}}, "label": "too far"}]}})
            counters = c.health()["counters"]
            # the kept scene's attach and detach: link poses and contacts by the pool too
            far = {"id": "far", "shape": "sphere", "radius": 0.02, "xyz": [0.0, 0.0, 3.0]}
            got = c.request("scene/apply", {"attach": [{"object": far, "link": link}],
                                            "state": {}})
            assert got["attached"] == 1
            with pytest.raises(errors.InvalidRequest) as touching:
                c.request("scene/apply", {"attach": [{"object": {
                    "id": "ball", "shape": "sphere", "radius": 0.05, "xyz": ball_at},
                    "link": link}], "state": {}})
            detached = c.request("scene/apply", {"detach": ["far"], "state": {}})
            (free,) = c.request("scene")["objects"]
    finally:
        assert srv.stop(signal.SIGINT) == 0, "\n".join(srv.stderr_lines[-20:])
    assert len(planned) == 1 and planned[0]["event"] == "planned", planned
    assert [s["kind"] for s in planned[0]["steps"]] and planned[0]["duration"] > 0
    assert all(s.get("verified", True) for s in planned[0]["steps"])
    err = bad[0]["error"]
    assert err["code"] == "INVALID_REQUEST" and err["details"]["step"] == 0, err
    assert err["details"]["error"]["details"]["joint"] == "joint_1"
    # both tasks were jobs of the pool: received and answered there
    assert counters["received"] == 2 and counters["ok"] == 1, counters
    assert ["ball", "horizontal_arm"] in touching.value.details["pairs"]
    assert detached["attached"] == 0 and free["id"] == "far"
    assert free["xyz"] == pytest.approx([0.0, 0.0, 3.0], abs=1e-9)  # where it was taken
    served = (modules / f"{srv.proc.pid}.txt").read_text().split()
    assert "arduinobot.service.task.task_service" in served  # it served the key
    loaded = [m for m in PLANNER_MODULES if m in served]
    assert not loaded, f"the serving process imported {loaded}"


def test_a_task_job_s_deadline_counts_every_step_s_planning_time():
    base = 100.0
    steps = [{"move": {"named": "home"}}, {"move": {"named": "home"}, "planning_time": 5.0},
             {"gripper": "open"}]
    assert job_deadline("task", {"task": {"steps": steps}}, base) == \
        base + 2 * DEFAULT_PLANNING_TIME + 5.0
    # the task's own planning_time is its steps' default; a tasks.yaml entry may be its
    # steps alone; a malformed value counts as the default (the worker refuses it)
    assert job_deadline("task", {"task": {"steps": steps, "planning_time": 2.0}}, base) == \
        base + 2 * 2.0 + 5.0
    assert job_deadline("task", {"task": steps}, base) == base + 2 * DEFAULT_PLANNING_TIME + 5.0
    bad = [{"move": {}, "planning_time": "soon"}, {"move": {}, "planning_time": True}]
    assert job_deadline("task", {"task": {"steps": bad}}, base) == \
        base + 2 * DEFAULT_PLANNING_TIME


def _snapshot(revision: int, n: int) -> SceneSnapshot:
    return SceneSnapshot(revision, tuple(
        Obstacle(id=f"box{i}", shape="box", xyz=(0.5, 0.1 * i, 0.0), size=(0.05, 0.05, 0.05))
        for i in range(n)))


def test_a_slot_sends_a_scene_once_per_worker_and_snapshot():
    slot = Slot.__new__(Slot)  # only its scene bookkeeping: no pool, no worker process
    slot._held = (None, None)
    a, b = _snapshot(3, 20), _snapshot(4, 20)
    w1, w2 = WorkerProcess(1, None, None), WorkerProcess(2, None, None)  # type: ignore[arg-type]
    assert slot._scene_for(w1, a) is a
    assert slot._scene_for(w1, a) == HELD_SCENE
    # an equal snapshot that is another object is sent again: identity, not equality
    assert slot._scene_for(w1, _snapshot(3, 20)) is not HELD_SCENE
    assert slot._scene_for(w1, b) is b and slot._scene_for(w1, b) == HELD_SCENE
    assert slot._scene_for(w2, b) is b  # a new worker holds nothing
    assert slot._scene_for(w2, None) is None and slot._scene_for(w2, None) is None


class _Recorder:
    """Stands in for a worker's Handlers: records the scene each fk job got."""

    def __init__(self) -> None:
        self.scenes: list[Any] = []

    def handle(self, kind: str, data: Any, *, scene: Any = None) -> dict[str, Any]:
        self.scenes.append(scene)
        return {"kind": kind}


def _serve(handlers: _Recorder) -> tuple[Any, threading.Thread, list[BaseException],
                                         TakenMark]:
    ours, theirs = Pipe()
    errors: list[BaseException] = []
    taken, fd = TakenMark.create()
    os.close(fd)

    def run() -> None:
        try:
            serve_jobs(theirs, handlers, taken)  # type: ignore[arg-type]
        except BaseException as e:  # noqa: BLE001 -- the test reads it
            errors.append(e)
        theirs.close()
    t = threading.Thread(target=run, daemon=True)
    t.start()
    return ours, t, errors, taken


def _outcome(conn: Any) -> Any:
    msg = conn.recv()
    assert isinstance(msg, Done)  # a job at the default deadline: no other message
    return msg.outcome


def test_a_worker_answers_a_held_scene_job_against_the_snapshot_it_holds():
    rec = _Recorder()
    conn, t, errors, taken = _serve(rec)
    a, b = _snapshot(3, 20), _snapshot(4, 2)
    for i, scene in enumerate((a, HELD_SCENE, b, HELD_SCENE, None)):
        conn.send(JobMsg(f"j{i}", "fk", {"joints": {}}, 1e12, scene, seq=i + 1))
        out = _outcome(conn)
        assert isinstance(out, Success) and orjson.loads(out.body)["request_id"] == f"j{i}"
        assert taken.seq == i + 1  # marked as it arrived
    conn.send(Stop())
    t.join(5.0)
    assert not errors
    assert rec.scenes == [a, a, b, b, None]
    # the held snapshot itself, not a copy sent again
    assert rec.scenes[1] is rec.scenes[0] and rec.scenes[3] is rec.scenes[2]


def test_a_held_scene_job_for_a_worker_that_holds_none_ends_it():
    conn, t, errors, taken = _serve(_Recorder())
    conn.send(JobMsg("j0", "fk", {"joints": {}}, 1e12, HELD_SCENE, seq=7))
    t.join(5.0)
    assert taken.seq == 7  # it had the job: a slot would not give it to another worker
    # a bug in the pool's bookkeeping: the worker ends (its job answered INTERNAL by the
    # slot, as for any worker that dies), it never answers against a guessed scene
    assert len(errors) == 1 and "none is held" in str(errors[0])


@pytest.mark.slow
def test_one_worker_answers_each_job_against_the_scene_of_its_arrival():
    # one worker: every check goes to it; the scene changes between them, so it is sent
    # the new snapshot each time the revision moves and holds it otherwise
    from arduinobot.client.client import PlannerClient
    d = load_description()
    path = [j.name for j in d.robot.link_path("horizontal_arm")]
    at = link_pose(d.robot, "horizontal_arm", path, np.zeros(len(path)))[:3, 3].tolist()
    srv = start_server(["--workers", "1", "--no-robot"])
    try:
        with PlannerClient(srv.endpoint, timeout=60) as c:
            assert c.check_state({}).valid and c.check_state({}).valid  # the same scene
            c.request("scene/apply", {"add": [{"id": "ball", "shape": "sphere",
                                               "radius": 0.05, "xyz": at}]})
            hit = c.check_state({})
            assert not hit.valid
            assert any(set(p) == {"ball", "horizontal_arm"} for p in hit.pairs), hit.pairs
            assert not c.check_state({}).valid  # the held snapshot
            c.request("scene/apply", {"remove": ["ball"]})
            assert c.check_state({}).valid
            # the claw under the plane the base stands on: the kept scene's world has the
            # ground, and the client turns it off (issue 38, item 5)
            under = {"joint_1": -0.4, "joint_2": -1.2, "joint_3": 0.4, "joint_4": -0.2}
            hit = c.check_state(under)
            assert any("ground" in p for p in hit.pairs) and not hit.valid, hit.pairs
            assert c.check_state(under, ground=False).valid
    finally:
        assert srv.stop(signal.SIGINT) == 0
