"""Faults of the host, through real `arduinobot serve` processes: a stopped worker (SIGSTOP)
is timed out and replaced; SIGTERM with requests in flight answers each of them (a
result or SHUTTING_DOWN), exits 0 and leaves no process behind."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from tests.helpers.procs import is_alive, process_tree, wait_for
from tests.helpers.serve import start_server
from tests.service.test_service_pool import LONG_PLAN

pytestmark = pytest.mark.slow  # every test starts its own serve


def _collect(fn, out: list) -> threading.Thread:
    def run():
        try:
            out.append(fn())
        except errors.ServiceError as e:  # collected for the assertions
            out.append(e)
    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def test_a_stopped_worker_times_out_then_the_service_recovers():
    srv = start_server(["--workers", "1", "--timeout", "1"])
    try:
        with PlannerClient(srv.endpoint, timeout=60) as c:
            pid = c.health()["workers"][0]["pid"]
            os.kill(pid, signal.SIGSTOP)
            with pytest.raises(errors.RequestTimeout) as e:
                c.fk({"joint_1": 0.1})
            assert "worker" in e.value.message
            assert c.fk({"joint_1": 0.2}).joints["joint_1"] == pytest.approx(0.2)
            assert c.health()["workers"][0]["pid"] not in (None, pid)
            wait_for(lambda: not is_alive(pid))  # killed and reaped, not left stopped
            assert c.health()["counters"]["timeouts_in_worker"] == 1
    finally:
        assert srv.stop(signal.SIGINT) == 0, "\n".join(srv.stderr_lines[-20:])


def test_sigterm_answers_every_request_in_flight_exits_0_and_leaves_no_process():
    srv = start_server(["--workers", "2", "--queue", "8"])
    with PlannerClient(srv.endpoint, timeout=60) as c:
        outs: list = []
        threads = [_collect(lambda: c.plan(LONG_PLAN), outs) for _ in range(2)]
        wait_for(lambda: all(w["busy"] for w in c.health()["workers"]))
        threads += [_collect(lambda i=i: c.fk({"joint_1": 0.1 * i}), outs) for i in range(3)]
        wait_for(lambda: c.health()["queue_depth"] == 3)
        procs = set(process_tree(srv.proc.pid))
        assert len(procs) >= 4  # server, zygote, two workers (and the forkserver)
        assert srv.stop(signal.SIGTERM) == 0, "\n".join(srv.stderr_lines[-20:])
        for t in threads:
            t.join(30)
    assert len(outs) == 5
    # every request answered: a result or SHUTTING_DOWN, never silence (UNAVAILABLE)
    assert all(isinstance(o, errors.ShuttingDown) or not isinstance(o, Exception)
               for o in outs), outs
    assert sum(isinstance(o, errors.ShuttingDown) for o in outs) >= 2  # the 20 s plans
    wait_for(lambda: not any(is_alive(p) for p in procs), timeout=10)
