"""The pool's workers: the zygote that forks them (:class:`Workers`), and one slot thread
per worker that feeds it jobs, watches it (deadline, memory cap, death), kills and
replaces it (what the job is answered in each case: :mod:`arduinobot.service.process.pool`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from arduinobot.contract.codes import Code
from arduinobot.service import hoptrace
from arduinobot.service.messages import (
    HELD_SCENE,
    Deadline,
    Done,
    Failure,
    JobMsg,
    Outcome,
    receive,
)
from arduinobot.service.messages import Stop as StopMsg
from arduinobot.service.process.job import Job, Stop, failure, shutting_down, stopped, timed_out
from arduinobot.service.process.worker import DescriptionSpec
from arduinobot.service.process.zygote import WorkerProcess, Zygote, ZygoteError

_log = logging.getLogger(__name__)

#: how often a busy worker's reply, memory and the shutdown grace are looked at [s]
_POLL = 0.05
_PAGE = os.sysconf("SC_PAGE_SIZE")


def rss_bytes(pid: int) -> int:
    """Resident set size of process ``pid`` [bytes] (0 once it is gone)."""
    try:
        with open(f"/proc/{pid}/statm", "rb") as f:
            return int(f.read().split()[1]) * _PAGE
    except (OSError, IndexError, ValueError):
        return 0


class JobQueue(Protocol):
    """What a slot needs from the pool (:class:`arduinobot.service.process.pool.WorkerPool`); a protocol, so
    the pool imports its slots and not the other way round."""

    stopping: bool
    workers: int
    grace_end: float  # when running jobs stop getting time after close [monotonic s]
    memory_cap: int | None

    def next_job(self, slot: Slot) -> Job | None: ...
    def finish(self, job: Job, outcome: Outcome) -> None: ...
    def requeue(self, job: Job) -> None: ...
    def count(self, key: str) -> None: ...
    def served(self, seconds: float) -> None: ...
    def set_busy(self, slot: Slot, job: Job | None) -> None: ...


class Workers:
    """The zygote and the live workers' pids, guarded by the pool's condition (the zygote
    reports every exit at once, so an idle worker's death is noticed without a job).

    Args:
        ctx, spec: as for :class:`~arduinobot.service.process.zygote.Zygote`.
        cond: the pool's condition: notified when a worker ends.
        count: adds one to one of the pool's counters (worker_restarts, ...).
    """

    def __init__(self, ctx: Any, spec: DescriptionSpec, cond: threading.Condition, *,
                 count: Callable[[str], None]) -> None:
        self._ctx, self._spec, self._cond, self._count = ctx, spec, cond, count
        self._live: set[int] = set()  # pids of the slots' current workers
        self._exits: dict[int, str] = {}  # ... that ended: how
        self._zygote: Zygote | None = None
        self._zygote_lock = threading.Lock()
        self.stopping = False

    @property
    def zygote_pid(self) -> int | None:
        return None if self._zygote is None else self._zygote.pid

    def start(self) -> None:
        """Start a zygote (it builds the model), in place of the last one if any.

        Raises:
            ZygoteError: it could not.
        """
        self._zygote = Zygote(self._ctx, self._spec, on_exit=self._on_exit,
                              on_lost=self._on_lost)

    def close(self) -> None:
        self.stopping = True
        if self._zygote is not None:
            self._zygote.close()

    def live_pid(self, worker: WorkerProcess | None) -> int | None:
        """``worker``'s pid while it runs, else None (call with the condition held)."""
        return None if worker is None or worker.pid in self._exits else worker.pid

    def fork(self) -> WorkerProcess:
        """A new warm worker, registered as live.

        Raises:
            ZygoteError: the zygote is gone or did not fork.
        """
        zygote = self._zygote
        if zygote is None:  # before start() or after a failed restart
            raise ZygoteError("the worker zygote is not running")
        w = zygote.fork()
        with self._cond:
            self._live.add(w.pid)
        return w

    def fork_until_stopping(self, name: str) -> WorkerProcess | None:
        """A new warm worker, re-starting the zygote if it is gone; None once stopping."""
        while not self.stopping:
            try:
                w = self.fork()
                self._count("worker_restarts")
                return w
            except ZygoteError as e:
                _log.warning("%s: %s", name, e)
            with self._zygote_lock:
                if self.stopping or (self._zygote is not None and self._zygote.alive):
                    continue
                try:
                    if self._zygote is not None:
                        self._zygote.close(timeout=0.5)
                    self.start()
                    self._count("zygote_restarts")
                except ZygoteError:
                    _log.exception("the worker zygote could not be restarted; retrying")
                    time.sleep(1.0)
        return None

    def retire(self, w: WorkerProcess, *, kill: bool) -> str | None:
        """Forget ``w`` (killing it first if asked); how it ended if known."""
        if kill:
            with contextlib.suppress(ProcessLookupError):  # it died on its own meanwhile
                os.kill(w.pid, signal.SIGKILL)
        with self._cond:
            self._cond.wait_for(lambda: w.pid in self._exits, 0.0 if kill else 1.0)
            how = self._exits.pop(w.pid, None)
            self._live.discard(w.pid)
        w.conn.close()
        return how

    def _on_exit(self, pid: int, how: str) -> None:
        with self._cond:
            if pid in self._live:
                self._exits[pid] = how
                self._cond.notify_all()

    def _on_lost(self) -> None:
        if not self.stopping:
            _log.error("the worker zygote ended; starting a new one (the model is built "
                       "again)")


class Slot:
    """One worker and the thread that feeds and watches it (see the module)."""

    def __init__(self, index: int, workers: Workers, queue: JobQueue) -> None:
        self.index, self._workers, self._queue = index, workers, queue
        self.name = f"worker {index}"
        self.worker: WorkerProcess | None = None
        self._rss_due = 0.0  # when the busy worker's memory is read next [monotonic s]
        #: (worker, the scene snapshot it was sent last): a job against the same
        #: snapshot object sends HELD_SCENE instead of the snapshot again
        self._held: tuple[WorkerProcess | None, Any] = (None, None)
        #: the number of the last job sent (its worker marks it taken: see TakenMark)
        self._seq = 0
        #: a job the pool handed to this idle slot, sent to its worker by the submitting
        #: thread (guarded by the pool's condition)
        self.handed: Job | None = None

    def live_pid(self) -> int | None:
        """The pid of this slot's worker while it runs (call with the pool's lock held)."""
        return self._workers.live_pid(self.worker)

    def run(self) -> None:
        """The slot's thread: until the pool stops."""
        q = self._queue
        while True:
            if self.worker is not None and self.live_pid() is None and not q.stopping:
                how = self._workers.retire(self.worker, kill=False)
                self.worker = None
                q.count("worker_crashes")
                _log.error("idle %s died (%s); replacing it", self.name, how)
            if self.worker is None:
                self.worker = self._workers.fork_until_stopping(self.name)
                if self.worker is None:
                    return
            if not self._serve_next():
                self._stop_worker()
                return

    def _serve_next(self) -> bool:
        """Serve the next job, if any; False once the pool stops. (A method of its own so
        no frame keeps an answered job alive while the slot waits.)"""
        q = self._queue
        job = q.next_job(self)
        if job is None:
            return not q.stopping
        if job.handoff is None and job.deadline <= time.monotonic():
            q.finish(job, timed_out(job, "while it waited for a worker"))
        elif self.worker is not None:
            self._run(self.worker, job)
        return True

    def _stop_worker(self) -> None:
        w = self.worker
        if w is None:
            return
        with contextlib.suppress(OSError):  # already gone
            w.conn.send(StopMsg())
        self._workers.retire(w, kill=False)
        self.worker = None

    def dispatch(self, job: Job) -> None:
        """Send ``job`` (handed to this idle slot by the pool) to the worker, on the
        submitting thread; then let the slot's thread watch it. The slot's thread waits
        for this send before it reads the worker's replies or could retire it (so no
        send goes to a socket closed, and its descriptor reused, meanwhile)."""
        assert job.handoff is not None  # the pool handed it: see WorkerPool.submit
        w = self.worker
        try:
            if w is None:  # cannot be while the slot waits idle; said, not assumed
                raise RuntimeError(f"{self.name} has no worker")
            self._send(w, job)
        except OSError:
            pass  # the worker died: its slot sees the socket end and re-dispatches it
        except Exception as e:  # noqa: BLE001 -- the slot answers the job INTERNAL
            _log.exception("%s: sending request %s failed", self.name, job.request_id)
            job.handoff_error = f"{type(e).__name__}: {e}"
        finally:
            job.handoff.set()

    def _send(self, w: WorkerProcess, job: Job) -> None:
        trace = job.trace
        if trace is not None:
            trace["slot"] = hoptrace.now()
        self._seq += 1  # one job at a time per slot: no other thread counts meanwhile
        w.conn.send(JobMsg(job.request_id, job.kind, job.payload, job.base_deadline,
                           self._scene_for(w, job.scene), self._seq))
        if trace is not None:
            trace["sent"] = hoptrace.now()

    def _run(self, w: WorkerProcess, job: Job) -> None:
        q = self._queue
        q.set_busy(self, job)
        t0 = time.monotonic()
        outcome, stop = None, None
        self._rss_due = t0  # a first look as it starts (a worker already over the cap)
        trace = job.trace
        try:
            if job.handoff is None:
                self._send(w, job)
            else:  # sent by the submitting thread (dispatch): once that send is done
                job.handoff.wait()
                if job.handoff_error is not None:
                    q.finish(job, failure(job, Code.INTERNAL, "the request could not be "
                                          f"sent to a worker: {job.handoff_error}"))
                    return
            while outcome is None and (stop := self._why_stop(job, w)) is None:
                if not w.conn.poll(min(_POLL, max(0.0, job.deadline - time.monotonic()))):
                    continue
                msg = receive(w.conn)
                if msg is None:
                    break  # the worker died: below
                if isinstance(msg, Deadline):
                    job.deadline = msg.deadline
                elif isinstance(msg, Done):
                    outcome = msg.outcome
                    if trace is not None:
                        trace["done"] = hoptrace.now()
                        trace.update(zip(hoptrace.WORKER_STAMPS, msg.trace))
        except OSError:
            pass  # the worker died: neither an outcome nor a stop, handled below
        finally:
            q.set_busy(self, None)
        if outcome is not None:
            q.served(time.monotonic() - t0)
            if isinstance(outcome, Failure):
                outcome = failure(job, outcome.code, outcome.message, **outcome.details)
            q.finish(job, outcome)
            return
        if stop is not None:
            self._workers.retire(w, kill=True)
            self.worker = None
            q.count({"deadline": "timeouts_in_worker", "memory": "memory_kills",
                     "shutdown": "shutdown_kills"}[stop])
            q.finish(job, stopped(job, stop, q.memory_cap))
            return
        how = self._workers.retire(w, kill=False)
        self.worker = None
        if q.stopping:
            q.finish(job, shutting_down(job))
            return
        q.count("worker_crashes")
        if w.taken.seq != self._seq and job.redispatched < q.workers:
            # it died before receiving this job (killed while idle, the report not yet
            # in): the job is not the cause, so it goes first to the next worker (which
            # may have died the same way: once per worker, so a job that kills workers
            # before they can say they took it still ends)
            _log.error("%s died (%s) before taking request %s; re-dispatching it",
                       self.name, how, job.request_id)
            q.count("redispatched")
            job.redispatched += 1
            q.requeue(job)
            return
        _log.error("%s died (%s) on request %s; replacing it", self.name, how,
                   job.request_id)
        q.finish(job, failure(job, Code.INTERNAL, f"the worker process died "
                              f"({how or 'unknown'}) while planning this request; it has "
                              "been replaced", worker_exit=how))

    def _scene_for(self, w: WorkerProcess, scene: Any) -> Any:
        """What a JobMsg to ``w`` carries of ``scene``: HELD_SCENE when ``w`` was sent this
        very snapshot last (a snapshot is immutable: the same object, the same scene; a
        new worker holds none). Compared by identity: equality would walk the objects."""
        if scene is not None and self._held[0] is w and self._held[1] is scene:
            return HELD_SCENE
        self._held = (w, scene)
        return scene

    def _why_stop(self, job: Job, w: WorkerProcess) -> Stop | None:
        q = self._queue
        now = time.monotonic()
        if q.stopping and now >= q.grace_end:
            return "shutdown"
        if now >= job.deadline:
            return "deadline"
        if q.memory_cap is not None and now >= self._rss_due:
            # read every _POLL, not on each message the worker sends (a file read of
            # /proc on the pool's side while the worker starts on a request)
            self._rss_due = now + _POLL
            if rss_bytes(w.pid) > q.memory_cap:
                return "memory"
        return None
