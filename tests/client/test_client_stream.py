"""The client's stream follower with no service behind the key (real Zenoh, no serve):
the caller hears that nothing answered, by its code, not a silent wait."""

from __future__ import annotations

import threading

import pytest
import zenoh

from arduinobot.client.client import PlannerClient
from arduinobot.client.errors import MalformedReply, ServiceUnavailable
from arduinobot.client.named_task import run_named_task
from arduinobot.contract.zconfig import zenoh_config
from tests.helpers.serve import free_port


@pytest.fixture
def lonely_client():
    ep = f"tcp/127.0.0.1:{free_port()}"
    with zenoh.open(zenoh_config(mode="peer", listen=[ep], connect=[])), \
            PlannerClient(ep, prefix="nobody_here", timeout=5) as c:
        yield c


def test_a_task_nobody_serves_is_unavailable_by_its_reason(lonely_client) -> None:
    with pytest.raises(ServiceUnavailable) as e:
        lonely_client.task("pick")
    assert e.value.reason == "no_route" and e.value.details["key"] == "nobody_here/task"
    with pytest.raises(ServiceUnavailable) as ex:
        lonely_client.execute(plan={"goal": {"named": "home"}})
    assert ex.value.reason == "no_route"


def test_the_ros2_runner_answers_false_when_nobody_serves(lonely_client) -> None:
    progress: list[float] = []
    assert not run_named_task(lonely_client.session, "nobody_here", 1,
                              on_progress=progress.append, cancel=threading.Event())
    assert progress == []


def test_reaction_events_parse_and_read_as_one_line() -> None:
    from arduinobot.client.stream import ExecutionEvent, describe
    changed = ExecutionEvent.parse({
        "event": "changed", "execution": "x1", "revision": 7, "added": ["box"],
        "removed": [], "attached": [], "detached": [], "certified": False, "action": "stop",
        "refused": {"time": 1.25, "pair": ["claw_support", "box"]}})
    assert describe(changed) == ("scene revision 7 (added box): the rest is no longer "
                                 "certified at 1.250 s (claw_support/box): stop")
    stopped = ExecutionEvent.parse({"event": "stopped", "execution": "x1", "revision": 7,
                                    "stop_ms": 212.4, "rest_at": 0.9, "before": True})
    assert describe(stopped) == ("stopped for revision 7: stop command 212 ms after the "
                                 "apply arrived, at rest at 0.900 s of the trajectory "
                                 "(before the first uncertified piece)")
    failed = ExecutionEvent.parse({"event": "replanned", "execution": "x1", "ok": False,
                                   "error": {"code": "NO_PATH_FOUND", "message": "none"}})
    assert describe(failed) == "replanning failed: NO_PATH_FOUND: none"
    assert describe(ExecutionEvent.parse({"event": "progress", "execution": "x1"})) is None
    with pytest.raises(MalformedReply):
        ExecutionEvent.parse({"event": "paused", "execution": "x1"})
