"""Faults around the service, with a real router process (``python -m arduinobot.service.router``):
the router restarting under load, and a cache folder that is full or cannot be written."""

from __future__ import annotations

import errno
import shutil
import subprocess
import threading
import time
from dataclasses import dataclass

import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from tests.helpers.procs import wait_for
from tests.helpers.serve import free_port, start_server, start_servers
from tests.helpers.zrouter import start_router

pytestmark = pytest.mark.slow  # every test starts serves (and a router)

PLAN = {"goal": {"named": "reach_left"}, "seed": 2}


@dataclass(frozen=True)
class Outcome:
    started: float   # [s] monotonic
    ended: float     # [s] monotonic
    error: errors.ServiceError | None


def _load(client: PlannerClient, stop: threading.Event, out: list[Outcome]) -> None:
    """Plan until ``stop``; every request's outcome goes to ``out``."""
    seed = 0
    while not stop.is_set():
        t0 = time.monotonic()
        try:
            client.plan(PLAN, seed=seed)
            out.append(Outcome(t0, time.monotonic(), None))
        except errors.ServiceError as e:
            out.append(Outcome(t0, time.monotonic(), e))
            stop.wait(0.05)  # a client's own back-off while the router is away
        seed += 1


def test_a_router_restart_mid_load_loses_no_reply_unannounced():
    """Three clients plan through a router that is SIGKILLed and restarted on the same
    port. Every request either gets its plan or a ServiceUnavailable saying the link was
    down (no_route, connected False) or the reply did not come in time; none hangs, no
    other error appears, and every client plans again after the restart on its own
    session."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = start_router(endpoint)
    srv = None
    clients: list[PlannerClient] = []
    try:
        srv = start_server(["--workers", "1", "--connect", endpoint])
        clients = [PlannerClient(endpoint, timeout=15) for _ in range(3)]
        stop = threading.Event()
        outs: list[list[Outcome]] = [[] for _ in clients]
        threads = [threading.Thread(target=_load, args=(c, stop, o), daemon=True)
                   for c, o in zip(clients, outs)]
        for t in threads:
            t.start()
        wait_for(lambda: all(sum(o.error is None for o in out) >= 3 for out in outs),
                 timeout=60, what="each client planned 3 times before the restart")
        issued_before = [len(o) for o in outs]
        killed_at = time.monotonic()
        router = router.restart()
        wait_for(lambda: all(any(o.error is None and o.started > killed_at for o in out)
                             for out in outs),
                 timeout=60, what="each client planned again after the restart")
        stop.set()
        for t in threads:
            t.join(30)
        assert not any(t.is_alive() for t in threads), "a request never returned"
        for out, before in zip(outs, issued_before):
            assert len(out) > before
            for o in out:
                if o.error is None:
                    continue
                assert isinstance(o.error, errors.ServiceUnavailable), repr(o.error)
                assert o.error.reason in ("no_route", "timeout"), o.error.message
                assert o.ended - o.started <= 15 + 5  # the client's timeout, then told
                if o.error.reason == "no_route" and not o.error.details["connected"]:
                    assert "link to" in o.error.message and "down" in o.error.message
        # the service kept serving: what it answered is at least what the clients got
        with PlannerClient(endpoint, timeout=15) as c:
            served = c.health()["counters"]["ok"]
        assert served >= sum(o.error is None for out in outs for o in out)
    finally:
        for c in clients:
            c.close()
        if srv is not None:
            assert srv.stop() == 0
        router.stop()


def _full_tmpfs(path) -> bool:
    """Mount a 64 KiB tmpfs at ``path`` and fill it (needs root); False if not allowed."""
    path.mkdir()
    if shutil.which("mount") is None:
        return False
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(path)],
                       capture_output=True)
    if r.returncode != 0:
        return False
    with open(path / "filler", "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"\0" * 4096)
        except OSError as e:
            if e.errno != errno.ENOSPC:
                raise
    return True


@pytest.fixture
def cache_dirs(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    dirs = {"unwritable": blocker / "cache"}  # every mkdir under a file fails (ENOTDIR)
    full = tmp_path / "full"
    if _full_tmpfs(full):
        dirs["full"] = full
    yield dirs
    if "full" in dirs:
        subprocess.run(["umount", str(full)], check=True)


def test_a_full_or_unwritable_cache_folder_still_serves_and_warns(cache_dirs):
    kinds = list(cache_dirs)
    servers = start_servers([["--workers", "1", "--cache-dir", str(cache_dirs[k])]
                             for k in kinds])
    try:
        for kind, srv in zip(kinds, servers):
            with PlannerClient(srv.endpoint, timeout=30) as c:
                res = c.plan(PLAN)
                assert res.duration > 0, kind
                assert c.fk({"joint_1": 0.1}).joints["joint_1"] == pytest.approx(0.1)
            warned = [ln for ln in srv.stderr_lines if "cannot write the cache entry" in ln]
            assert warned, (kind, srv.stderr_lines[-20:])
    finally:
        for srv in servers:
            srv.stop()
    if "full" not in cache_dirs:
        pytest.skip("a full disk needs a tmpfs mount (root): tested an unwritable one only")
