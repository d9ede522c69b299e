"""A running task reacts to the kept scene changing (service/execute/task_react.py,
service/plan/task_recheck.py): through a real `arduinobot serve` driving the MuJoCo twin
of the course workspace, the two-step pick and place (``pick box``, ``place box`` at
``bin``) runs; while it picks, a sphere is put where the carried box passes on the way to
the bin. Each remaining step is re-checked with what the task carries there (the box from
the attach on), so the change is refused in the place's move; with ``stop`` the arm stops
(the twin's joint states, checked by FCL on the link meshes and on the carried box, each
placed by an independent forward kinematics, touch nothing) and the report names the
step; with ``replan`` the task's remaining steps are planned again and the box ends in
the bin; with ``ignore`` the box goes through the sphere (the same check finds it); a
change off the path lets the task go on. No wall-clock bounds: the stream's events."""

from __future__ import annotations

import threading
from typing import Any

import fcl
import numpy as np
import pytest

from arduinobot.client.client import PlannerClient
from arduinobot.description import load_description
from tests.helpers.contact import LinkMeshes
from tests.helpers.fk import link_pose
from tests.helpers.joint_states import States
from tests.helpers.pick_place import BIN_INNER, BIN_XY, BOX, pick_and_place_by_name
from tests.helpers.serve import start_server

pytestmark = pytest.mark.slow

APPLY_AFTER = 0.3  # [s] into the pick's approach move (task step 0's second step)
HELD = "claw_support"  # the course claw's holding link


@pytest.fixture(scope="module")
def served(course_ws):
    srv = start_server(["--workers", "1", str(course_ws.xacro), "--package-dir",
                        str(course_ws.src), "--moveit-config", str(course_ws.moveit_pkg)],
                       timeout=240)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def course(course_ws):
    return load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})


@pytest.fixture(scope="module")
def meshes(course):
    return LinkMeshes(course)


def _task(c: PlannerClient, course) -> dict[str, Any]:
    """The two-step pick and place from where the arm is (the same task plans alike)."""
    c.apply(clear=True)
    state = c.robot_state()
    start = {n: float(v) for n, v in zip(state["name"], state["position"])
             if n in course.robot.actuated_joints}
    return {**pick_and_place_by_name(), "start": start}


def _pose(xyz, rpy=(0.0, 0.0, 0.0)) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    t = np.eye(4)
    t[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    t[:3, 3] = xyz
    return t


class Carried:
    """The box as the task carries it: fixed to the holding link from the attach on,
    where the box was on the table at the attach state (forward kinematics of its own)."""

    def __init__(self, course, planned) -> None:
        self.robot, self.names = course.robot, list(planned.joint_names)
        attach = next(s for s in planned.steps if s["kind"] == "attach")
        assert attach["object"] == "box" and attach["link"] == HELD
        q = [attach["start"][n] for n in self.names]
        box = next(o for o in planned.planned["obstacles"] if o["id"] == "box")
        self.rel = np.linalg.inv(link_pose(self.robot, HELD, self.names, q)) \
            @ _pose(box["xyz"], box.get("rpy", (0, 0, 0)))
        self.obj = fcl.CollisionObject(fcl.Box(*box["size"]), fcl.Transform())

    def at(self, names: list[str], q) -> np.ndarray:
        return link_pose(self.robot, HELD, names, q) @ self.rel

    def hits(self, names: list[str], states: np.ndarray, sphere: dict) -> list[int]:
        """The states at which the box, held, would touch ``sphere`` (every state: the
        box is taken as held even before the attach, which only adds states)."""
        ob = fcl.CollisionObject(fcl.Sphere(sphere["radius"]),
                                 fcl.Transform(np.eye(3), np.asarray(sphere["xyz"])))
        out = []
        for k, q in enumerate(states):
            t = self.at(names, q)
            self.obj.setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
            if fcl.collide(self.obj, ob, fcl.CollisionRequest(), fcl.CollisionResult()):
                out.append(k)
        return out


def _on_the_way(planned, carried: Carried) -> dict:
    """A sphere around the carried box halfway along the place's move to the bin."""
    move = next(s for s in planned.steps if s["part_of"] == 1 and s["kind"] == "move")
    traj = move["plan"]["trajectory"]
    pts = traj["points"]
    q = pts[len(pts) // 2]["positions"]
    # under the box's bottom (the fingers hold it from the sides): only the box meets it
    at = carried.at(list(traj["joint_names"]), q) @ _pose([0.0, 0.0, 0.0])
    centre = at[:3, 3] - np.array([0.0, 0.0, BOX / 2 + 0.02])
    return {"id": "intruder", "shape": "sphere", "radius": 0.03,
            "xyz": [float(v) for v in centre]}


def _run(c: PlannerClient, task: dict, on_change: str, add: list[dict]
         ) -> tuple[Any, list[dict]]:
    """Execute ``task`` with ``on_change``; APPLY_AFTER into the pick's approach move
    put ``add`` in the kept scene; the reply and every event."""
    events: list[dict] = []
    applied = threading.Event()
    planned: dict = {}

    def on_planned(p) -> None:
        planned.update(p)

    def on_event(ev) -> None:
        events.append(dict(ev.raw))
        if ev.event != "progress" or applied.is_set() or not planned:
            return
        approach = planned["steps"][1]
        if ev.raw.get("time", 0.0) >= approach["start_time"] + APPLY_AFTER:
            applied.set()
            threading.Thread(target=c.apply, kwargs={"add": add}, daemon=True).start()
    reply = c.task(task, execute=True, on_change=on_change, on_planned=on_planned,
                   on_event=on_event)
    assert applied.is_set()
    return reply, events


def _kinds(events: list[dict]) -> list[str]:
    return [e["event"] for e in events if e["event"] != "progress"]


def test_an_obstacle_where_the_carried_box_will_pass_stops_the_task(served, course, meshes):
    with PlannerClient(served.endpoint, timeout=120) as c:
        task = _task(c, course)
        planned = c.task(task)
        carried = Carried(course, planned)
        ob = _on_the_way(planned, carried)
        # on the planned way the carried box meets the sphere, the arm's links do not
        move = next(s for s in planned.steps if s["part_of"] == 1 and s["kind"] == "move")
        way_names = list(move["plan"]["trajectory"]["joint_names"])
        way = np.array([p["positions"] for p in move["plan"]["trajectory"]["points"]])
        assert carried.hits(way_names, way, ob)
        assert meshes.contacts(way_names, way, ob) == []
        states = States(c)
        try:
            reply, events = _run(c, task, "stop", [ob])
        finally:
            states.close()
        report = reply.report
        assert report["outcome"] == "stopped", report
        assert report["stopped_because"] == "on_change is stop"
        assert _kinds(events) == ["started", "changed", "stopped", "finished"], events
        changed = next(e for e in events if e["event"] == "changed")
        assert changed["certified"] is False and changed["action"] == "stop"
        assert changed["added"] == ["intruder"]
        # refused in the place's move, with the carried box; the arm was picking
        assert changed["step"]["task_step"] == 1 and changed["step"]["task_kind"] == "place"
        assert changed["step"]["kind"] == "move"
        assert "box" in changed["refused"]["pair"] and "intruder" in changed["refused"]["pair"]
        assert changed["running"]["task_step"] == 0
        assert changed["running"]["task_kind"] == "pick"
        stopped = next(e for e in events if e["event"] == "stopped")
        assert stopped["before"] is True, stopped
        assert stopped["rest_at"] <= stopped["certified_until"] <= changed["refused"]["time"]
        # it rests before the refused step (in the pick, unless the check came late)
        assert stopped["step"]["index"] < changed["step"]["index"]
        assert report["stopped_in"] == stopped["step"]
        assert stopped["refused_step"] == changed["step"]
        names, qs = states.arrays()
        assert meshes.contacts(names, qs, ob) == []
        assert carried.hits(names, qs, ob) == []
        print(f"\ntask stop: {stopped['stop_ms']:.0f} ms from the apply to the stop "
              f"command, recheck {changed['recheck_ms']:.0f} ms; at rest "
              f"{stopped['rest_at']:.2f} s in step {stopped['step']}")


def test_a_change_off_the_path_lets_the_task_put_the_box_in_the_bin(served, course):
    far = {"id": "far_box", "shape": "box", "size": [0.2, 0.2, 0.2],
           "xyz": [-1.5, -1.5, 0.1]}
    with PlannerClient(served.endpoint, timeout=120) as c:
        task = _task(c, course)
        reply, events = _run(c, task, "stop", [far])
        report = reply.report
        assert report["outcome"] == "completed" and "legs" not in report, report
        assert _kinds(events) == ["started", "changed", "finished"], events
        changed = next(e for e in events if e["event"] == "changed")
        assert changed["certified"] is True and changed["action"] == "continued"
        assert changed["added"] == ["far_box"] and changed["running"]["task_step"] == 0
        sim = report["objects"]["box"]
        assert np.all(np.abs(np.subtract(sim[:2], BIN_XY)) < BIN_INNER / 2 - BOX / 2)


def test_with_replan_the_task_plans_its_remaining_steps_and_puts_the_box_in_the_bin(
        served, course, meshes):
    with PlannerClient(served.endpoint, timeout=120) as c:
        task = _task(c, course)
        planned = c.task(task)
        carried = Carried(course, planned)
        ob = _on_the_way(planned, carried)
        states = States(c)
        try:
            reply, events = _run(c, task, "replan", [ob])
        finally:
            states.close()
        report = reply.report
        assert report["outcome"] == "completed", report
        assert len(report["legs"]) == 2 and report["legs"][0]["outcome"] == "stopped"
        assert "stopped_in" not in report and "stopped_because" not in report
        assert _kinds(events) == ["started", "changed", "stopped", "replanned", "finished"]
        stopped = next(e for e in events if e["event"] == "stopped")
        assert stopped["before"] is True
        replanned = next(e for e in events if e["event"] == "replanned")
        # stopped in the pick before its attach: the pick and the place, planned again;
        # after it (the box held), the place
        assert replanned["ok"] is True, replanned
        attach = next(s["index"] for s in planned.steps if s["kind"] == "attach")
        assert replanned["from_step"] == ({"task_step": 0, "kind": "pick"}
                                          if stopped["step"]["index"] < attach
                                          else {"task_step": 1, "kind": "place"})
        names, qs = states.arrays()
        assert meshes.contacts(names, qs, ob) == []
        assert carried.hits(names, qs, ob) == []
        # the published motion never jumps across the stop and the new leg
        assert np.abs(np.diff(qs[:, :4], axis=0)).max() < 0.05
        # MuJoCo's box: let go over the bin's place, dropped on its floor, within 1 cm
        let_go = task["places"]["bin"]["position"]
        floor = next(o for o in task["obstacles"] if o["id"] == "bin_floor")
        want = [let_go[0], let_go[1], floor["xyz"][2] + floor["size"][2] / 2 + BOX / 2]
        sim = report["objects"]["box"]
        assert np.linalg.norm(np.subtract(sim, want)) < 0.01, (sim, want)


def test_with_ignore_the_task_goes_through_what_it_was_told_of(served, course, meshes):
    with PlannerClient(served.endpoint, timeout=120) as c:
        task = _task(c, course)
        planned = c.task(task)
        carried = Carried(course, planned)
        ob = _on_the_way(planned, carried)
        states = States(c)
        try:
            reply, events = _run(c, task, "ignore", [ob])
        finally:
            states.close()
        report = reply.report
        assert report["outcome"] == "completed" and "legs" not in report, report
        assert _kinds(events) == ["started", "changed", "finished"], events
        changed = next(e for e in events if e["event"] == "changed")
        assert changed["certified"] is False and changed["action"] == "ignored"
        assert changed["step"]["task_kind"] == "place"
        # the sphere was where the carried box went: the same independent check finds it
        # in a state after the arm was where the box was attached
        names, qs = states.arrays()
        attach = next(s for s in planned.steps if s["kind"] == "attach")
        cols = [i for i, n in enumerate(names) if n in attach["start"]]
        q_attach = np.array([attach["start"][names[i]] for i in cols])
        at = [k for k, q in enumerate(qs) if np.abs(q[cols] - q_attach).max() < 0.03]
        assert at
        assert [k for k in carried.hits(names, qs, ob) if k > at[0]]
