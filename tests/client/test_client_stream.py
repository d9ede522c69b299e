"""The client's stream follower with no service behind the key (real Zenoh, no serve):
the caller hears that nothing answered, by its code, not a silent wait."""

from __future__ import annotations

import threading

import pytest
import zenoh

from arduinobot.client.client import PlannerClient
from arduinobot.client.errors import ServiceUnavailable
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
