"""The serving process's memory does not grow with the clients it has served.

bench/soak.py found the server's resident set growing 16 MiB per client session: Zenoh
1.10 carries any message over 3 KB between processes on one host through a 16 MiB
shared-memory pool per session, which the server mapped and kept mapped after the client
left. The service turns Zenoh's shared memory off (arduinobot.service.server.ServeOptions)."""

from __future__ import annotations

from pathlib import Path

import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient

# over Zenoh's 3 KB threshold for its shared-memory transport; refused by the schema
BIG = b'{"joints": {"joint_1": 0.1}, "pad": "' + b"a" * 8000 + b'"}'


def _zenoh_shm_mappings(pid: int) -> list[str]:
    """The Zenoh shared-memory segments (``<id>.zenoh``) mapped into process ``pid``."""
    return [line.split()[-1] for line in Path(f"/proc/{pid}/maps").read_text().splitlines()
            if line.rstrip().endswith(".zenoh")]


def _rss_shmem(pid: int) -> int:
    """Resident shared memory of process ``pid`` [KiB]."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("RssShmem:"):
            return int(line.split()[1])
    raise AssertionError("no RssShmem in /proc/<pid>/status")


def test_clients_sending_large_requests_leave_no_shared_memory_in_the_server(server):
    shm0 = _rss_shmem(server.proc.pid)
    for _ in range(3):  # three sessions, as three `arduinobot` commands would open
        with PlannerClient(server.endpoint, timeout=30) as c:
            with pytest.raises(errors.InvalidRequest) as e:
                c.request("fk", BIG)
            assert e.value.details["field"] == "pad"
            assert c.fk({"joint_1": 0.2}).joints["joint_1"] == pytest.approx(0.2)
    assert _zenoh_shm_mappings(server.proc.pid) == []
    # with Zenoh's default, 3 sessions added 3 x 16 MiB here
    assert _rss_shmem(server.proc.pid) - shm0 < 4 * 1024
