"""The worker pool under stress, through a real server: BUSY, TIMEOUT, a worker killed
mid-request (INTERNAL, then replaced), exactly one reply per request, clean Ctrl-C."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from clients import errors
from clients.client import PlannerClient

from .conftest import start_server

# RRTstar uses its whole planning time; the sphere blocks the straight line, so the
# planner really runs (the pipeline tries a straight line first).
LONG_PLAN = {"start": {"joint_1": -1.2, "joint_2": 1.2, "joint_3": 0.3},
             "goal": {"joints": {"joint_1": 1.2, "joint_2": 1.2, "joint_3": 0.3}},
             "obstacles": [{"id": "ball", "shape": "sphere", "radius": 0.2,
                            "xyz": [-0.15, -0.49, 2.33]}],
             "planner": "RRTstar", "planning_time": 20.0, "seed": 1}


@pytest.fixture(scope="module")
def small_server():
    """One worker, one queue slot, 0.3 s deadline (plus planning_time for plans)."""
    srv = start_server(["--workers", "1", "--queue", "1", "--timeout", "0.3"])
    yield srv
    code = srv.stop(signal.SIGINT)
    assert code == 0, "\n".join(srv.stderr_lines[-20:])
    assert any("shutting down" in ln for ln in srv.stderr_lines)


def _in_thread(fn):
    out: dict = {}

    def run():
        try:
            out["value"] = fn()
        except Exception as e:  # noqa: BLE001 -- collected for the assertions below
            out["error"] = e
    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t, out


def _wait_for(cond, timeout=30.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = cond()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError("condition not reached")


def test_busy_timeout_and_a_killed_worker(small_server):
    with PlannerClient(small_server.endpoint, timeout=60) as c:
        pid0 = c.health()["workers"][0]["pid"]
        long_t, long_out = _in_thread(lambda: c.plan(LONG_PLAN))
        _wait_for(lambda: c.health()["workers"][0]["busy"])
        queued_t, queued_out = _in_thread(lambda: c.fk({"joint_1": 0.1}))
        _wait_for(lambda: c.health()["queue_depth"] == 1)
        t0 = time.monotonic()
        with pytest.raises(errors.ServiceBusy):
            c.fk({"joint_1": 0.2})
        assert time.monotonic() - t0 < 1.0  # refused at once, not after the deadline
        queued_t.join(10)
        assert isinstance(queued_out.get("error"), errors.RequestTimeout), queued_out
        assert long_t.is_alive()  # still planning
        os.kill(pid0, signal.SIGKILL)
        long_t.join(10)
        err = long_out.get("error")
        assert isinstance(err, errors.InternalError), long_out
        assert "SIGKILL" in err.message
        # the worker is replaced and the next request succeeds
        _wait_for(lambda: c.health()["workers"][0]["pid"] not in (None, pid0))
        assert c.fk({"joint_1": 0.3}).joints["joint_1"] == pytest.approx(0.3)
        h = c.health()
        assert h["workers"][0]["pid"] not in (None, pid0)
        cnt = h["counters"]
        assert cnt["BUSY"] == 1 and cnt["TIMEOUT"] == 1 and cnt["INTERNAL"] == 1
        assert cnt["worker_crashes"] == 1 and cnt["worker_restarts"] == 1
        # exactly one reply per request: received == answered (health is not counted)
        answered = sum(cnt.get(k, 0) for k in ("ok", "BUSY", "TIMEOUT", "INTERNAL"))
        assert cnt["received"] == 4 and answered == 4


@pytest.fixture(scope="module")
def tight_server():
    """One worker and a 1 ms deadline beyond planning_time: a plan's work after planning
    (simplification, dense re-check, timing, verification) always takes longer."""
    srv = start_server(["--workers", "1", "--queue", "1", "--timeout", "0.001"])
    yield srv
    assert srv.stop(signal.SIGINT) == 0, "\n".join(srv.stderr_lines[-20:])


def test_a_request_past_its_deadline_in_a_worker_times_out_and_the_worker_is_replaced(
        tight_server):
    # RRTstar spends its whole 0.05 s planning time; the rest of the pipeline then runs
    # past the deadline inside the worker, which must be replaced.
    req = {**LONG_PLAN, "planning_time": 0.05}
    with PlannerClient(tight_server.endpoint, timeout=60) as c:
        _wait_for(lambda: c.health()["workers"][0]["pid"])
        before = c.health()
        pid0 = before["workers"][0]["pid"]
        with pytest.raises(errors.RequestTimeout) as e:
            c.plan(req)
        assert "worker" in e.value.message
        _wait_for(lambda: c.health()["workers"][0]["pid"] not in (None, pid0))
        cnt = c.health()["counters"]
        assert cnt["timeouts_in_worker"] == before["counters"].get("timeouts_in_worker", 0) + 1
        assert cnt["worker_restarts"] == before["counters"].get("worker_restarts", 0) + 1


def test_ctrl_c_answers_the_request_in_flight_and_exits_cleanly(small_server):
    # last in this module: it stops the module's server
    with PlannerClient(small_server.endpoint, timeout=60) as c:
        t, out = _in_thread(lambda: c.plan(LONG_PLAN))
        _wait_for(lambda: c.health()["workers"][0]["busy"])
        t0 = time.monotonic()
        assert small_server.stop(signal.SIGINT) == 0
        t.join(10)
        assert time.monotonic() - t0 < 10
        err = out.get("error")
        assert isinstance(err, errors.ShuttingDown) and "shutting down" in err.message, out
