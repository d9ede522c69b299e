"""Two instances behind a router (a zenoh session in router mode, in this process):
clients spread work over both, and a plain get fails over when one is killed."""

from __future__ import annotations

import json
import signal
import time

import pytest
import zenoh

from clients.client import PlannerClient
from service.zconfig import zenoh_config

from .conftest import free_port, start_servers


@pytest.fixture(scope="module")
def cluster():
    port = free_port()
    router = zenoh.open(zenoh_config(mode="router", listen=[f"tcp/127.0.0.1:{port}"]))
    endpoint = f"tcp/127.0.0.1:{port}"
    servers = []
    try:
        servers = start_servers([["--workers", "1", "--connect", endpoint]] * 2)
        yield endpoint, servers
    finally:
        for s in servers:
            s.stop()
        router.close()


def _wait_instances(c: PlannerClient, n: int, timeout: float = 20.0) -> tuple[str, ...]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        live = c.instances(refresh=True)
        if len(live) == n:
            return live
        time.sleep(0.1)
    raise AssertionError(f"expected {n} live instances, saw {c.instances(refresh=True)}")


def test_spread_requests_reach_both_instances(cluster):
    endpoint, servers = cluster
    with PlannerClient(endpoint, spread=True, timeout=30) as c:
        live = _wait_instances(c, 2)
        assert set(live) == {s.instance for s in servers}
        ids = [c.fk({"joint_1": 0.01 * i}).request_id for i in range(6)]
        plans = [c.plan(goal={"named": "reach_left"}, seed=i) for i in range(2)]
        served = {rid.split("-")[0] for rid in ids + [p.request_id for p in plans]}
        assert served == {s.instance[:8] for s in servers}
        for inst in live:
            assert c.health(instance=inst)["counters"]["ok"] >= 4


def test_a_plain_get_fails_over_when_an_instance_dies(cluster):
    endpoint, servers = cluster
    session = zenoh.open(zenoh_config(mode="client", connect=[endpoint], listen=[]))
    try:
        def plain_fk() -> str | None:
            replies = list(session.get("arduinobot/fk", payload=b'{"joints": {}}', timeout=10))
            if not replies or replies[0].ok is None:
                return None
            return json.loads(replies[0].ok.payload.to_bytes())["request_id"].split("-")[0]

        first = plain_fk()
        assert first is not None
        victim = next(s for s in servers if s.instance.startswith(first))
        survivor = next(s for s in servers if s is not victim)
        victim.stop(signal.SIGKILL)
        deadline = time.monotonic() + 10
        answered = None
        while time.monotonic() < deadline and answered is None:
            answered = plain_fk()
        assert answered == survivor.instance[:8]
        assert all(plain_fk() == survivor.instance[:8] for _ in range(5))
        with PlannerClient(endpoint, spread=True, timeout=30) as c:
            assert _wait_instances(c, 1) == (survivor.instance,)
            assert c.fk({"joint_1": 0.2}).joints["joint_1"] == pytest.approx(0.2)
    finally:
        session.close()
