"""`arduinobot serve` as a real subprocess: the one launcher of the tests and the benches.

Tests import it (through tests/conftest.py's fixtures, or directly), benches import it as
``tests.helpers.serve`` (``python -m bench.NAME`` from the repository root); it imports
nothing of either.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from .procs import REPO, launch_all, stop_process

__all__ = ["REPO", "Server", "free_port", "launch_serves", "start_server", "start_servers"]

#: what `arduinobot serve` logs once its workers are ready and its keys are declared
READY = "service ready"
#: where the servers the tests start keep their planning scene unless told
#: (--scene-file), one file each: never the user's own (~/.local/state/arduinobot),
#: which a test's applies would change and whose objects would be in every test's plans
_STATE = tempfile.TemporaryDirectory(prefix="arduinobot-test-state-")


def _scene_file() -> str:
    """A scene file of its own for one server (a test that means to share one passes
    --scene-file)."""
    return str(tempfile.mkdtemp(dir=_STATE.name)) + "/scene.json"


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
        """Send ``sig`` and wait ``timeout`` [s], then kill; returns the exit code."""
        return stop_process(self.proc, sig, timeout)

    @property
    def instance(self) -> str:
        return self.ready_line.split("instance ", 1)[1].split(",", 1)[0]


def start_server(args: Sequence[str] = (), *, port: int | None = None,
                 timeout: float = 90.0, env: Mapping[str, str] | None = None) -> Server:
    """Start `arduinobot serve ARGS` listening on 127.0.0.1 (multicast scouting off, its
    default) and wait for its ready line."""
    return start_servers([args], timeout=timeout, ports=[port], env=env)[0]


def start_servers(arg_lists: Sequence[Sequence[str]], *, timeout: float = 90.0,
                  ports: Sequence[int | None] | None = None,
                  env: Mapping[str, str] | None = None) -> list[Server]:
    """Start several servers at once (their workers load in parallel), each listening on
    its own loopback port; wait for all."""
    endpoints = [f"tcp/127.0.0.1:{port or free_port()}"
                 for port in (ports or [None] * len(arg_lists))]
    return launch_serves([["--listen", e, *args] for e, args in zip(endpoints, arg_lists)],
                         endpoints=endpoints, timeout=timeout, env=env)


def launch_serves(arg_lists: Sequence[Sequence[str]], *, endpoints: Sequence[str] | None = None,
                  timeout: float = 90.0, env: Mapping[str, str] | None = None
                  ) -> list[Server]:
    """`arduinobot serve` with exactly these arguments (``endpoints``: where each
    listens, for :class:`Server`; "" if none), all at once; waits for every ready line.

    Raises:
        procs.LaunchError: one exited or was not ready within ``timeout`` [s].
    """
    argvs = [[sys.executable, "-m", "arduinobot.cli.main", "serve", *args,
              *([] if "--scene-file" in args else ["--scene-file", _scene_file()])]
             for args in arg_lists]
    launched = launch_all(argvs, ready=READY, what="arduinobot serve", env=env,
                          timeout=timeout)
    return [Server(p.proc, endpoint, p.ready_line, p.lines)
            for p, endpoint in zip(launched, endpoints or [""] * len(arg_lists))]
