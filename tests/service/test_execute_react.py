"""A moving arm reacts to the kept scene changing (service/execute/react.py): through a
real `arduinobot serve` driving the MuJoCo twin, an obstacle put on the path while the
arm moves makes it stop before it (the twin's recorded joint states, checked by FCL on
the link meshes with an independent forward kinematics, touch nothing), and with
``replan`` it goes on to the goal; ``stop`` leaves it stopped; ``ignore`` goes through
(the same check finds the contact: the obstacle was on the path); a change off the path
does not stop it. No wall-clock bounds: a slow motion, and the stream's events."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from arduinobot.client.client import PlannerClient
from tests.helpers.contact import LinkMeshes
from tests.helpers.joint_states import States
from tests.helpers.serve import start_server

pytestmark = pytest.mark.slow

# a slow motion (~5 s) from home: time to hear, check and stop
GOAL = {"joints": {"joint_1": -1.0, "joint_2": 0.3, "joint_3": 0.5}}
SLOW = {"goal": GOAL, "velocity_scaling": 0.03, "acceleration_scaling": 0.03, "seed": 7}
APPLY_AT = 0.15  # progress at which the obstacle is put in
ON_PATH_AT = 0.5  # where on the planned path the obstacle is put [fraction of time]


@pytest.fixture(scope="module")
def served():
    srv = start_server(["--workers", "1"])
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def meshes(desc):
    return LinkMeshes(desc)


def _home(c: PlannerClient) -> None:
    c.apply(clear=True)
    done = c.execute(plan={"goal": {"named": "home"}}, move_to_start=True)
    assert done.report["outcome"] == "completed"


def _on_path(c: PlannerClient, desc) -> dict:
    """A sphere around the claw where the planned motion has it at ON_PATH_AT of its
    time (the same request from the same state: the service plans it alike)."""
    from tests.helpers.fk import link_pose
    plan = c.plan({**SLOW, "start": {n: float(v) for n, v in zip(
        c.robot_state()["name"], c.robot_state()["position"])
        if n in desc.robot.actuated_joints}})
    q = plan.positions[int(ON_PATH_AT * (len(plan.times) - 1))]
    at = link_pose(desc.robot, "claw_support", list(plan.joint_names), q)[:3, 3]
    return {"id": "intruder", "shape": "sphere", "radius": 0.08,
            "xyz": [float(v) for v in at]}


def _run(c: PlannerClient, on_change: str, add: list[dict]) -> tuple[dict, list[dict]]:
    """Execute SLOW with ``on_change``; at APPLY_AT put ``add`` in the kept scene; the
    finished report and every event."""
    events: list[dict] = []
    applied = threading.Event()

    def on_event(ev) -> None:
        events.append(dict(ev.raw))
        if ev.event == "progress" and ev.raw.get("progress", 0) >= APPLY_AT \
                and not applied.is_set():
            applied.set()
            threading.Thread(target=c.apply, kwargs={"add": add}, daemon=True).start()
    done = c.execute(plan=SLOW, on_change=on_change, on_event=on_event)
    assert applied.is_set()
    return dict(done.report), events


def _kinds(events: list[dict]) -> list[str]:
    return [e["event"] for e in events if e["event"] not in ("progress",)]


def _at_rest_late(states: States) -> None:
    # the executor's settle ends once every joint is below 0.01 rad/s
    assert np.abs(states.msgs[-1]["velocity"]).max() < 0.01


def test_an_obstacle_on_the_path_stops_the_arm_before_it(served, desc, meshes):
    with PlannerClient(served.endpoint, timeout=60) as c:
        _home(c)
        ob = _on_path(c, desc)
        states = States(c)
        try:
            report, events = _run(c, "stop", [ob])
            time.sleep(0.5)  # later states: the arm stays where it stopped
            after = c.robot_state()["position"]
        finally:
            states.close()
        assert report["outcome"] == "stopped", report
        assert report["stopped_because"] == "on_change is stop"
        assert _kinds(events) == ["started", "changed", "stopped", "finished"], events
        changed = next(e for e in events if e["event"] == "changed")
        assert changed["certified"] is False and changed["action"] == "stop"
        assert changed["added"] == ["intruder"]
        stopped = next(e for e in events if e["event"] == "stopped")
        assert stopped["before"] is True, stopped
        assert stopped["stop_kind"] == "path"
        assert stopped["rest_at"] <= stopped["certified_until"] <= changed["refused"]["time"]
        assert stopped["stop_ms"] > 0
        names, qs = states.arrays()
        assert meshes.contacts(names, qs, ob) == []
        _at_rest_late(states)
        assert np.allclose(after, qs[-1], atol=1e-3)
        assert all(v <= 1 + 1e-6 for v in report["peak_ratio"].values())
        print(f"\nstop: {stopped['stop_ms']:.0f} ms from the apply to the stop command, "
              f"recheck {changed['recheck_ms']:.0f} ms; at rest {stopped['rest_at']:.2f} s, "
              f"certified until {stopped['certified_until']:.2f} s, refused at "
              f"{changed['refused']['time']:.2f} s")


def test_with_replan_the_arm_goes_around_to_the_goal(served, desc, meshes):
    with PlannerClient(served.endpoint, timeout=60) as c:
        _home(c)
        ob = _on_path(c, desc)
        states = States(c)
        try:
            report, events = _run(c, "replan", [ob])
        finally:
            states.close()
        assert report["outcome"] == "completed", report
        assert len(report["legs"]) == 2 and report["legs"][0]["outcome"] == "stopped"
        assert _kinds(events) == ["started", "changed", "stopped", "replanned", "finished"]
        assert next(e for e in events if e["event"] == "stopped")["before"] is True
        assert next(e for e in events if e["event"] == "replanned")["ok"] is True
        goal = [GOAL["joints"][n] for n in ("joint_1", "joint_2", "joint_3")]
        assert report["final_positions"][:3] == pytest.approx(goal, abs=2e-3)
        names, qs = states.arrays()
        assert meshes.contacts(names, qs, ob) == []
        # the published motion never jumps across the stop and the new leg
        assert np.abs(np.diff(qs[:, :4], axis=0)).max() < 0.05


def test_with_ignore_the_arm_goes_through_what_it_was_told_of(served, desc, meshes):
    with PlannerClient(served.endpoint, timeout=60) as c:
        _home(c)
        ob = _on_path(c, desc)
        states = States(c)
        try:
            report, events = _run(c, "ignore", [ob])
        finally:
            states.close()
        assert report["outcome"] == "completed" and "legs" not in report
        assert _kinds(events) == ["started", "changed", "finished"]
        changed = events[[e["event"] for e in events].index("changed")]
        assert changed["certified"] is False and changed["action"] == "ignored"
        # the obstacle was on the path: the same independent check finds the contact
        names, qs = states.arrays()
        assert meshes.contacts(names, qs, ob)


def test_a_change_off_the_path_lets_the_arm_go_on(served, desc):
    far = {"id": "far_box", "shape": "box", "size": [0.2, 0.2, 0.2],
           "xyz": [-1.5, -1.5, 0.1]}
    with PlannerClient(served.endpoint, timeout=60) as c:
        _home(c)
        report, events = _run(c, "stop", [far])
        assert report["outcome"] == "completed" and "legs" not in report
        assert _kinds(events) == ["started", "changed", "finished"]
        changed = events[[e["event"] for e in events].index("changed")]
        assert changed["certified"] is True and changed["action"] == "continued"
        assert changed["added"] == ["far_box"]
