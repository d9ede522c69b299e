"""The zygote: one process that builds the model once and forks warm workers on demand.

Building the planner costs seconds (tens on CAD meshes); forking a process that already
holds it costs milliseconds, and the fork shares its pages copy-on-write. So the pool
starts one zygote, asks it for a worker per slot, and asks again whenever a worker dies
or is killed (deadline, memory cap): the next request is served by a warm process at once.

The zygote is started through :mod:`multiprocessing`'s forkserver, never by
forking a process that holds a Zenoh session; it never plans after its warm-up, and it
is single-threaded when it forks. Each worker gets its own socket, passed to the pool
over the zygote's control pipe. The zygote reaps its workers and reports each exit at
once (``SIGCHLD``), so the pool notices an idle worker's death without sending it a job.
Workers die with the zygote (``PR_SET_PDEATHSIG``), and the zygote with the pool (EOF on
its pipe): no orphans, even after a SIGKILL of the server.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import itertools
import logging
import os
import signal
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing import reduction
from multiprocessing.connection import Connection, wait
from typing import Any

from arduinobot.service.messages import (
    Exited,
    Fork,
    Forked,
    Ready,
    StartFailed,
    Stop,
    TakenMark,
    receive,
)
from arduinobot.service.process.worker import DescriptionSpec, build_handlers, serve_jobs

_log = logging.getLogger(__name__)

_PR_SET_PDEATHSIG = 1


class ZygoteError(RuntimeError):
    """The zygote could not build the model, or it is gone."""


@dataclass(frozen=True)
class WorkerProcess:
    """A warm worker forked by the zygote: its pid, the pool's end of its socket, and
    the mark it sets on each job it receives."""

    pid: int
    conn: Connection
    taken: TakenMark


def describe_status(status: int) -> str:
    """``waitpid`` status -> ``"signal SIGKILL"`` or ``"exit code 1"``."""
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            return f"signal {signal.Signals(sig).name}"
        except ValueError:
            return f"signal {sig}"
    return f"exit code {os.waitstatus_to_exitcode(status)}"


# -- the zygote process ---------------------------------------------------------------
#: the loggers that warn about the model (its loading, the limits derived from it)
_MODEL_LOGGERS = ("arduinobot.description", "arduinobot.planner.kinematics.limits")


def _said_by_the_server(record: logging.LogRecord) -> bool:
    """The model's warnings at DEBUG here: the serving process loaded the same model and
    logged each of them once (they were said again by the zygote, twice for the derived
    limits, on every start)."""
    if record.levelno == logging.WARNING and record.name.startswith(_MODEL_LOGGERS):
        record.levelno, record.levelname = logging.DEBUG, logging.getLevelName(logging.DEBUG)
        return logging.getLogger().isEnabledFor(logging.DEBUG)
    return True


def zygote_main(conn: Connection, spec: DescriptionSpec, log_level: int) -> None:
    """The zygote process: build the handlers, then fork workers and report their exits
    until :class:`~arduinobot.service.messages.Stop` or EOF (the messages: :mod:`arduinobot.service.messages`)."""
    # Ctrl-C reaches the whole process group: the pool shuts everything down itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    logging.basicConfig(level=log_level,
                        format="%(asctime)s %(levelname)s %(name)s[%(process)d]: %(message)s")
    for handler in logging.getLogger().handlers:
        handler.addFilter(_said_by_the_server)
    from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
    # as the command line sets it for -v / -vv (the serving process leaves it to us)
    set_ompl_log_level("debug" if log_level <= logging.DEBUG else
                       "info" if log_level <= logging.INFO else "none")
    # say what a slow start is doing: CAD meshes make the geometry the long part
    logging.getLogger("arduinobot.service").setLevel(min(logging.INFO, log_level))
    _die_with_parent()
    try:
        handlers = build_handlers(spec)
    except Exception as e:  # noqa: BLE001 -- reported to the pool, which refuses to start
        conn.send(StartFailed(f"{type(e).__name__}: {e}"))
        return
    # What the model holds lives as long as every worker: out of the collector's sight
    # (a full collection in a worker would walk it all, on a request's time, and write
    # to every page of it that the forks share copy-on-write)
    gc.collect()
    gc.freeze()
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    signal.signal(signal.SIGCHLD, lambda *_: None)  # the wakeup fd carries it
    signal.set_wakeup_fd(wake_w)
    conn.send(Ready())
    try:
        while True:
            for ready in wait([conn, wake_r]):
                if ready == wake_r:
                    os.read(wake_r, 4096)
                    _report_exits(conn)
                    continue
                msg = receive(conn)
                if msg is None:
                    return
                if not isinstance(msg, Fork):
                    raise TypeError(f"the zygote takes Fork, not {type(msg).__name__}")
                _fork(conn, msg.token, handlers, (wake_r, wake_w))
    finally:
        # workers still running die with us (PR_SET_PDEATHSIG); the pool has already
        # asked each to stop after its job
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)


def _fork(conn: Connection, token: int, handlers: Any, wake: tuple[int, int]) -> None:
    ours, theirs = socket.socketpair()
    taken, taken_fd = TakenMark.create()
    pid = os.fork()
    if pid == 0:  # the worker: never returns into the zygote's loop
        code = 0
        try:
            signal.set_wakeup_fd(-1)
            signal.signal(signal.SIGCHLD, signal.SIG_DFL)
            for fd in wake:
                os.close(fd)
            conn.close()
            ours.close()
            _die_with_parent()
            os.close(taken_fd)
            serve_jobs(Connection(theirs.detach()), handlers, taken)
        except BaseException:  # noqa: BLE001 -- logged; the pool sees the exit code
            _log.exception("worker %d failed outside a job", os.getpid())
            code = 1
        finally:
            logging.shutdown()
            os._exit(code)
    theirs.close()
    conn.send(Forked(token, pid))
    reduction.send_handle(conn, ours.fileno(), os.getppid())
    reduction.send_handle(conn, taken_fd, os.getppid())
    ours.close()
    os.close(taken_fd)
    del taken  # the zygote's map of it (the worker and the pool keep theirs)


def _report_exits(conn: Connection) -> None:
    while True:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        conn.send(Exited(pid, describe_status(status)))


def _die_with_parent() -> None:
    """Ask Linux to SIGKILL this process when its parent ends (no orphans)."""
    parent = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        _log.warning("PR_SET_PDEATHSIG unavailable: a worker may outlive a killed server")
        return
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


# -- the pool's handle on it ----------------------------------------------------------
class Zygote:
    """The zygote, started with the model built: fork workers from it, hear of their exits.

    Args:
        ctx: a :mod:`multiprocessing` context (forkserver).
        spec: how the zygote loads the description.
        on_exit: called ``(pid, how)`` on the reader thread when a worker ends.
        on_lost: called on the reader thread if the zygote itself ends.

    Raises:
        ZygoteError: it could not load the description (the message says why).
    """

    def __init__(self, ctx: Any, spec: DescriptionSpec, *,
                 on_exit: Callable[[int, str], None], on_lost: Callable[[], None]) -> None:
        self._on_exit, self._on_lost = on_exit, on_lost
        self._send_lock = threading.Lock()
        self._tokens = itertools.count(1)
        self._pending: dict[int, tuple[threading.Event, list[Any]]] = {}
        self.alive = True  # until the reader sees the zygote end
        parent, child = ctx.Pipe(duplex=True)
        self._proc = ctx.Process(target=zygote_main, name="arduinobot-zygote",
                                 args=(child, spec, logging.getLogger().level), daemon=True)
        self._proc.start()
        child.close()
        msg = receive(parent)  # None: it exited
        if not isinstance(msg, Ready):
            self._proc.join(1.0)
            why = msg.message if isinstance(msg, StartFailed) else repr(msg)
            if msg is None:
                why = f"it exited while building the model (exit code {self._proc.exitcode})"
            raise ZygoteError(f"the worker zygote could not start: {why}")
        self._conn: Connection = parent
        self.pid: int = self._proc.pid
        threading.Thread(target=self._read, name="zygote-reader", daemon=True).start()

    def fork(self, *, timeout: float = 10.0) -> WorkerProcess:
        """A new warm worker (milliseconds).

        Raises:
            ZygoteError: the zygote is gone or did not answer within ``timeout`` [s].
        """
        if not self.alive:
            raise ZygoteError("the worker zygote is not running")
        token = next(self._tokens)
        event = threading.Event()
        box: list[Any] = []
        self._pending[token] = (event, box)
        try:
            with self._send_lock:
                self._conn.send(Fork(token))
            if not event.wait(timeout) or not box:
                raise ZygoteError("the worker zygote did not fork a worker")
        except OSError as e:
            raise ZygoteError(f"the worker zygote is gone: {e}") from None
        finally:
            self._pending.pop(token, None)
        return box[0]

    def close(self, *, timeout: float = 2.0) -> None:
        """Stop it (its remaining workers die with it)."""
        with contextlib.suppress(OSError), self._send_lock:
            self._conn.send(Stop())
        self._proc.join(timeout)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join(1.0)
        self._conn.close()

    def _read(self) -> None:
        conn = self._conn
        try:
            while (msg := receive(conn)) is not None:
                if isinstance(msg, Forked):
                    fd = reduction.recv_handle(conn)
                    taken_fd = reduction.recv_handle(conn)
                    try:
                        taken = TakenMark(taken_fd)
                    finally:
                        os.close(taken_fd)
                    worker = WorkerProcess(msg.pid, Connection(fd), taken)
                    waiter = self._pending.get(msg.token)
                    if waiter is None:  # its requester gave up: do not leak it
                        worker.conn.close()
                        continue
                    waiter[1].append(worker)
                    waiter[0].set()
                elif isinstance(msg, Exited):
                    self._on_exit(msg.pid, msg.how)
        except OSError:
            pass  # the zygote ended (or we closed it): below
        self.alive = False
        for event, _ in list(self._pending.values()):
            event.set()
        self._on_lost()
