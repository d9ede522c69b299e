"""src/arduinobot/service/peers.py: a second instance started as a Zenoh peer of the
first, with no router between them, refuses to start (issue 39, item 2: both answered
every query: plans twice, scene applies twice, one execute moved both robots); the first
keeps serving, one reply a request. Behind a router two instances start (the cluster
tests, tests/service/test_service_cluster.py)."""

from __future__ import annotations

import json

import pytest
import zenoh

from arduinobot.contract.zconfig import zenoh_config
from tests.helpers.procs import LaunchError
from tests.helpers.serve import start_server, start_servers

pytestmark = pytest.mark.slow


def test_a_second_instance_as_a_peer_of_the_first_refuses_to_start():
    first = start_server(["--workers", "1"])
    try:
        with pytest.raises(LaunchError) as e:
            start_servers([["--workers", "1", "--connect", first.endpoint]])
        said = str(e.value)
        assert "exited with 1" in said
        assert "PeerInstances" in said and first.instance in said
        assert "router" in said and "--prefix" in said
        # the first serves on: one reply to a plan on the shared key
        with zenoh.open(zenoh_config(mode="client", connect=[first.endpoint],
                                     listen=[])) as s:
            replies = list(s.get("arduinobot/plan", payload=json.dumps(
                {"goal": {"named": "home"}, "seed": 1}), timeout=60))
        assert len(replies) == 1 and replies[0].ok is not None
        # another prefix beside it is no clash
        other = start_servers([["--workers", "1", "--connect", first.endpoint,
                                "--prefix", "arm2"]])[0]
        other.stop()
    finally:
        first.stop()
