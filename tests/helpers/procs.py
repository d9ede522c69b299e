"""Processes the tests and benches start: launching one and waiting for its ready line,
stopping one (or several at once), reading its state, finding its descendants.

Every `arduinobot serve` and router the tests and benches run starts here
(:func:`launch_all`), so a ready line is waited for one way, and the test suite can tell
a test that starts processes (:func:`launch_count`, checked against the ``slow`` marker
in tests/conftest.py).
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

REPO = Path(__file__).resolve().parents[2]

T = TypeVar("T")

_launches = 0
_launches_lock = threading.Lock()


class LaunchError(RuntimeError):
    """A process exited, or did not print its ready line in time."""


@dataclass
class Launched:
    """A running process started by :func:`launch_all`; a thread keeps reading its stderr
    into ``lines`` (so its pipe never fills)."""

    proc: subprocess.Popen
    argv: list[str]
    ready_line: str
    lines: list[str] = field(default_factory=list)

    def stop(self, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
        """Send ``sig`` and wait ``timeout`` [s], then kill; returns the exit code."""
        return stop_process(self.proc, sig, timeout)


def launch_count() -> int:
    """How many processes :func:`launch_all` has started in this Python process."""
    return _launches


def launch_all(argvs: Sequence[Sequence[str]], *, ready: str, what: str,
               env: Mapping[str, str] | None = None, timeout: float = 90.0
               ) -> list[Launched]:
    """Start every ``argv`` at once (cwd: the repository, stdout discarded, stderr read),
    then wait until each has printed a stderr line containing ``ready``.

    Args:
        ready: the text of the ready line (e.g. ``"service ready"``).
        what: what is started, for the error message.
        env: the environment (default: this process's), ``PYTHONUNBUFFERED=1`` added so
            a Python child's log lines arrive as they are written.
        timeout: for all of them together [s].

    Raises:
        LaunchError: one exited or was not ready in time (then every one is killed), with
            the last lines it printed.
    """
    global _launches
    env = {**(os.environ if env is None else env), "PYTHONUNBUFFERED": "1"}
    started = []
    for argv in argvs:
        proc = subprocess.Popen(list(argv), cwd=REPO, env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)
        with _launches_lock:
            _launches += 1
        lines: list[str] = []
        seen = threading.Event()
        threading.Thread(target=_pump, args=(proc, lines, ready, seen), daemon=True).start()
        started.append((proc, list(argv), lines, seen))
    deadline = time.monotonic() + timeout
    out = []
    for proc, argv, lines, seen in started:
        # the pump sets ``seen`` at the ready line; the process ending or the deadline
        # passing ends the wait instead
        while not seen.wait(0.1):
            if proc.poll() is not None or time.monotonic() > deadline:
                # said before the kill below sets every return code
                why = (f"exited with {proc.returncode}" if proc.returncode is not None
                       else f"not ready within {timeout:g} s")
                for p, *_ in started:
                    p.kill()
                    p.wait(5)
                raise LaunchError(f"{what} {why}:\n" + "\n".join(lines[-30:]))
        out.append(Launched(proc, argv, next(ln for ln in lines if ready in ln), lines))
    return out


def _pump(proc: subprocess.Popen, lines: list[str], ready: str,
          seen: threading.Event) -> None:
    for line in proc.stderr:  # type: ignore[union-attr]
        lines.append(line.rstrip("\n"))
        if ready in line:
            seen.set()


def stop_process(proc: subprocess.Popen, sig: int = signal.SIGINT, timeout: float = 20.0
                 ) -> int:
    """Send ``sig`` and wait ``timeout`` [s], then kill; returns the exit code."""
    return stop_processes([proc], sig, timeout)[0]


def stop_processes(procs: Iterable[subprocess.Popen], sig: int = signal.SIGINT,
                   timeout: float = 20.0) -> list[int]:
    """Send ``sig`` to every one first (they shut down in parallel), then wait for each
    ``timeout`` [s] and kill it if it is still running; their exit codes."""
    procs = list(procs)
    for p in procs:
        if p.poll() is None:
            p.send_signal(sig)
    for p in procs:
        try:
            p.wait(timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(5)
    return [p.returncode for p in procs]


def wait_for(cond: Callable[[], T], *, timeout: float = 30.0, what: str = "the condition",
             every: float = 0.05) -> T:
    """Poll ``cond`` every ``every`` [s] until it returns something true; that value.
    ``timeout`` [s] only bounds a failure: the wait ends as soon as ``cond`` holds.

    Raises:
        AssertionError: ``cond`` did not hold within ``timeout``.
    """
    deadline = time.monotonic() + timeout
    while True:
        value = cond()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"not within {timeout:g} s: {what}")
        time.sleep(every)


def cpu_seconds(pid: int) -> float:
    """CPU time process ``pid`` has used so far (user + system) [s], from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    # fields after the name: state is [0], utime [11], stime [12] (proc(5) 14 and 15)
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def wait_for_cpu(pid: int, seconds: float, *, timeout: float = 30.0) -> None:
    """Wait until process ``pid`` has used ``seconds`` [s] more CPU than it had now: it is
    working (e.g. a worker that has taken a job; an idle one waits without using any)."""
    start = cpu_seconds(pid)
    wait_for(lambda: cpu_seconds(pid) - start >= seconds, timeout=timeout,
             what=f"process {pid} using {seconds:g} s of CPU")


def is_alive(pid: int) -> bool:
    """Process ``pid`` exists and is not a zombie."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


def process_tree(root: int) -> list[int]:
    """``root`` and every descendant process (from /proc)."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                ppid = int(Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue  # it ended while we looked
            kids.setdefault(ppid, []).append(int(d))
    out, todo = [], [root]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(kids.get(p, []))
    return out
