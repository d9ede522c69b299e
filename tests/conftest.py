"""Shared fixtures: free loopback ports and `arduinobot serve` as a real subprocess."""

from __future__ import annotations

import inspect
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from .helpers.procs import stop_process

REPO = Path(__file__).resolve().parents[1]
#: where the servers the tests start keep their planning scene unless told
#: (--scene-file), one folder each: never the user's own (~/.local/state/arduinobot),
#: which a test's applies would change and whose objects would be in every test's plans
_STATE = tempfile.TemporaryDirectory(prefix="arduinobot-test-state-")


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Server:
    """A running `arduinobot serve` subprocess."""

    proc: subprocess.Popen
    endpoint: str
    ready_line: str
    stderr_lines: list[str] = field(default_factory=list)

    def stop(self, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
        """Send ``sig`` and wait; returns the exit code."""
        return stop_process(self.proc, sig, timeout)

    @property
    def instance(self) -> str:
        return self.ready_line.split("instance ", 1)[1].split(",", 1)[0]


def start_server(args: Sequence[str] = (), *, port: int | None = None,
                 timeout: float = 90.0) -> Server:
    """Start `arduinobot serve` listening on 127.0.0.1 (multicast scouting off, its
    default) and wait for its ready line."""
    return start_servers([args], timeout=timeout, ports=[port])[0]


def start_servers(arg_lists: Sequence[Sequence[str]], *, timeout: float = 90.0,
                  ports: Sequence[int | None] | None = None) -> list[Server]:
    """Start several servers at once (their workers load in parallel), wait for all."""
    endpoints = [f"tcp/127.0.0.1:{port or free_port()}"
                 for port in (ports or [None] * len(arg_lists))]
    return launch_serves([["--listen", e, *args] for e, args in zip(endpoints, arg_lists)],
                         endpoints=endpoints, timeout=timeout)


def launch_serves(arg_lists: Sequence[Sequence[str]], *, endpoints: Sequence[str] | None = None,
                  timeout: float = 90.0) -> list[Server]:
    """`arduinobot serve` with exactly these arguments (``endpoints``: where each
    listens, for :class:`Server`; "" if none), all at once; waits for every ready line."""
    launched = []
    for args, endpoint in zip(arg_lists, endpoints or [""] * len(arg_lists)):
        argv = [sys.executable, "-m", "clients.cli", "serve", *args]
        # each its own (a test that means to share a scene file passes --scene-file)
        state = tempfile.mkdtemp(dir=_STATE.name)
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "ARDUINOBOT_STATE": state}
        proc = subprocess.Popen(argv, cwd=REPO, env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)
        lines: list[str] = []
        ready = threading.Event()
        threading.Thread(target=_pump, args=(proc, lines, ready), daemon=True).start()
        launched.append((proc, endpoint, lines, ready))
    deadline = time.monotonic() + timeout
    servers = []
    for proc, endpoint, lines, ready in launched:
        while not ready.wait(0.2):
            if proc.poll() is not None or time.monotonic() > deadline:
                for p, *_ in launched:
                    p.kill()
                    p.wait(5)
                raise RuntimeError("arduinobot serve did not start:\n" + "\n".join(lines[-30:]))
        line = next(ln for ln in lines if "service ready" in ln)
        servers.append(Server(proc, endpoint, line, lines))
    return servers


def _pump(proc: subprocess.Popen, lines: list[str], ready: threading.Event) -> None:
    for line in proc.stderr:  # type: ignore[union-attr]
        lines.append(line.rstrip("\n"))
        if "service ready" in line:
            ready.set()


@pytest.fixture(scope="session")
def server() -> Iterator[Server]:
    """One `arduinobot serve` (2 workers) shared by the modules that only query it."""
    srv = start_server(["--workers", "2"])
    yield srv
    srv.stop()


@pytest.fixture(scope="session")
def client(server: Server):
    from clients.client import PlannerClient
    with PlannerClient(server.endpoint, timeout=30.0) as c:
        yield c


@pytest.fixture(scope="session")
def course_ws(tmp_path_factory):
    """A user's colcon workspace as ROS 2 and the MoveIt Setup Assistant leave it."""
    from .helpers.course_workspace import make_course_workspace
    return make_course_workspace(tmp_path_factory.mktemp("course_ws"))


# -- the `slow` marker: tests that start `arduinobot serve` (or router) processes or a browser
# (`./dev test -m "not slow"` is the quick loop; the default run, and CI, run everything)
_STARTS_PROCESSES = re.compile(
    r"\b(start_servers?|launch_serves|start_router|Browser|_chromium)\(|\"serve\"")
_PROCESS_FIXTURES = frozenset({"server", "client"})


def _starts_processes(fn: object) -> bool:
    try:
        return bool(_STARTS_PROCESSES.search(inspect.getsource(fn)))  # type: ignore[arg-type]
    except (OSError, TypeError):  # no source (a builtin fixture): it starts nothing of ours
        return False


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark ``slow`` every test that uses the shared server, or whose own code or any
    fixture it uses starts a server or the browser."""
    for item in items:
        fixturedefs = getattr(item, "_fixtureinfo", None)
        funcs = [getattr(item, "function", None)]
        if fixturedefs is not None:
            funcs += [d.func for defs in fixturedefs.name2fixturedefs.values() for d in defs]
        if _PROCESS_FIXTURES & set(getattr(item, "fixturenames", ())) or any(
                _starts_processes(f) for f in funcs if f is not None):
            item.add_marker(pytest.mark.slow)
