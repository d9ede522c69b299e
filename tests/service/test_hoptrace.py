"""src/arduinobot/service/hoptrace.py: with ARDUINOBOT_HOPTRACE set, a real serve stamps every stage of
each work request it answers, in order, on the clock clients on this host read too."""

from __future__ import annotations

import json
import os
import signal
import time

import pytest

from arduinobot.client.client import PlannerClient
from arduinobot.service import hoptrace
from tests.helpers.serve import start_server

#: the stamps a planned request gets, in the order they are taken ("sent", after the
#: slot's send returned, may come after the worker has read the job: not in it)
ORDER = ("callback", "queued", "slot", "w_recv", "w_decoded", "w_handled",
         "w_encoded", "done", "replied", "final")


@pytest.mark.slow
def test_a_traced_service_stamps_each_stage_in_order(tmp_path):
    trace = tmp_path / "hop.jsonl"
    srv = start_server(["--workers", "1"], env={**os.environ, hoptrace.ENV: str(trace)})
    try:
        with PlannerClient(srv.endpoint, timeout=60) as c:
            t0 = time.monotonic()
            plan = c.plan({"goal": {"named": "reach_left"}, "seed": 1})
            fk = c.fk({"joint_1": 0.2})
            t1 = time.monotonic()
    finally:
        assert srv.stop(signal.SIGINT) == 0
    lines = [json.loads(x) for x in trace.read_text().splitlines()]
    by_id = {x["request_id"]: x for x in lines}
    assert set(by_id) == {plan.request_id, fk.request_id}
    for rid, kind in ((plan.request_id, "plan"), (fk.request_id, "fk")):
        st = by_id[rid]["stamps"]
        assert by_id[rid]["kind"] == kind and set(st) == {*ORDER, "sent"}
        assert st["slot"] <= st["sent"] <= st["done"]
        times = [st[k] for k in ORDER]
        assert times == sorted(times), st
        # one clock with this process: the reply left after "done" (the client may have
        # it before query.reply returns, and returns before the query is finalised)
        assert t0 <= st["callback"] and st["done"] <= t1
    st = by_id[plan.request_id]["stamps"]
    # the planner ran between the worker's decode and its handler's end
    assert st["w_handled"] - st["w_decoded"] >= plan.timing["total"]


def test_tracing_is_off_without_the_variable():
    assert (hoptrace.PATH is None) == (not os.environ.get(hoptrace.ENV))
    assert hoptrace.ON == (hoptrace.PATH is not None)
