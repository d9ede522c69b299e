"""A pool of worker processes with a bounded queue, deadlines and exactly one reply per job.

One parent thread per worker slot feeds its process over a pipe and waits for the answer
with the job's deadline: when the deadline passes the job gets TIMEOUT and the process is
replaced (it may be stuck in native code); when the process dies (a crash in native code,
a signal) the job gets INTERNAL and the process is replaced. A watcher thread times out
jobs still waiting in the queue. Past ``queue_size`` waiting jobs, ``submit`` refuses at
once (BUSY). Replies are sent from these threads, never from Zenoh's.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import multiprocessing as mp
import queue
import signal
import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from .worker import DescriptionSpec, worker_main

_log = logging.getLogger(__name__)

#: ``(True, reply JSON bytes)`` or ``(False, {"code", "message", "details"})``.
Outcome = tuple[bool, Any]


class PoolStartError(RuntimeError):
    """A worker could not load the description or warm up."""


@dataclass(eq=False)
class Job:
    """One request in flight. ``respond`` is called exactly once (first outcome wins),
    then dropped, so whatever it holds (a Zenoh query) is released."""

    kind: str
    data: Mapping[str, Any]
    request_id: str
    deadline: float  # time.monotonic()
    respond: Callable[[Outcome], None] | None
    waiting: bool = False  # in the queue, counted against queue_size
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def done(self) -> bool:
        return self.respond is None

    def claim(self) -> Callable[[Outcome], None] | None:
        """Take the right to reply (once): the responder, or None if already taken."""
        with self._lock:
            fn, self.respond = self.respond, None
        return fn


def error(code: str, message: str, **details: Any) -> Outcome:
    return False, {"code": code, "message": message, "details": details}


def _waited_too_long(job: Job) -> Outcome:
    return error("TIMEOUT", "the request's deadline passed while it waited for a worker",
                 request_id=job.request_id)


class WorkerPool:
    """``workers`` processes, each with the description loaded once.

    Args:
        spec: how workers load the description.
        workers: number of processes (>= 1).
        queue_size: jobs that may wait for a free worker; more are refused (BUSY).
        start_method: ``forkserver`` (default; fast replacement) or ``spawn``.
    """

    def __init__(self, spec: DescriptionSpec, *, workers: int, queue_size: int,
                 start_method: str = "forkserver") -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        self.spec, self.workers = spec, workers
        self._ctx = mp.get_context(start_method)
        if start_method == "forkserver":
            # Children fork from a server that already imported the planner.
            # the planner's imports (trimesh, toppra, OMPL: ~2 s) are paid once, in the
            # forkserver, not again by every worker it forks
            self._ctx.set_forkserver_preload(["service.worker", "planner.pipeline"])
            # start it now: its imports run while the caller loads the description
            from multiprocessing import forkserver
            forkserver.ensure_running()
        # Unbounded: capacity counts waiting jobs, so one that timed out in the queue
        # frees its place at once rather than when a worker dequeues it.
        self._queue: queue.Queue[Job | None] = queue.Queue()
        self._waiting = 0
        self.queue_size = queue_size
        self.counters: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._pids: list[int | None] = [None] * workers
        self._busy: list[Job | None] = [None] * workers
        self._procs: list[Any] = [None] * workers
        self._heap: list[tuple[float, int, Job]] = []
        self._seq = itertools.count()
        self._cond = threading.Condition()
        self._stopping = False
        self._threads: list[threading.Thread] = []

    # -- lifecycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Start every worker and wait until each has loaded the description.

        Raises:
            PoolStartError: a worker failed to load (the message says why).
        """
        ready = [threading.Event() for _ in range(self.workers)]
        failures: list[str] = []
        for i in range(self.workers):
            t = threading.Thread(target=self._slot, args=(i, ready[i], failures),
                                 name=f"pool-slot-{i}", daemon=True)
            t.start()
            self._threads.append(t)
        for ev in ready:
            ev.wait()
        if failures:
            self.close()
            raise PoolStartError(failures[0])
        w = threading.Thread(target=self._watch, name="pool-deadlines", daemon=True)
        w.start()
        self._threads.append(w)

    def close(self, *, grace: float = 2.0) -> None:
        """Refuse new jobs, answer waiting ones with INTERNAL, give running ones ``grace``
        seconds [s], then stop the workers (their jobs get INTERNAL)."""
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        while True:
            try:
                job = self._queue.get_nowait()
            except queue.Empty:
                break
            if job is not None:
                self._finish(job, error("INTERNAL", "the service is shutting down"))
        for _ in range(self.workers):
            self._queue.put(None)
        end = time.monotonic() + grace
        for t in self._threads:
            t.join(timeout=max(0.0, end - time.monotonic()))
        for p in self._procs:
            if p is not None and p.is_alive():
                p.kill()
                p.join(1.0)
        for t in self._threads:
            t.join(timeout=2.0)

    def __enter__(self) -> WorkerPool:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- submitting --------------------------------------------------------------------
    def submit(self, job: Job) -> None:
        """Queue a job, or answer it BUSY at once when the queue is full."""
        self.count("received")
        if self._stopping:
            self._finish(job, error("INTERNAL", "the service is shutting down"))
            return
        with self._lock:
            full = self._waiting >= self.queue_size
            if not full:
                self._waiting += 1
                job.waiting = True
        if full:
            self._finish(job, error("BUSY", f"all {self.workers} workers are busy and "
                             f"{self.queue_size} requests are waiting; retry later",
                             workers=self.workers, queue_size=self.queue_size,
                             request_id=job.request_id))
            return
        self._queue.put(job)
        with self._cond:
            heapq.heappush(self._heap, (job.deadline, next(self._seq), job))
            self._cond.notify()

    def status(self) -> dict[str, Any]:
        """Workers (pid, busy request), queue depth and counters, JSON-ready."""
        with self._lock:
            workers = [{"pid": pid, "busy": None if j is None else j.request_id}
                       for pid, j in zip(self._pids, self._busy)]
            counters = dict(self.counters)
        return {"workers": workers, "queue_depth": self._waiting,
                "queue_size": self.queue_size, "counters": counters}

    # -- internals ---------------------------------------------------------------------
    def count(self, key: str) -> None:
        with self._lock:
            self.counters[key] += 1

    def _dequeued(self, job: Job) -> bool:
        """Take ``job`` out of the waiting count; False if someone else already did."""
        with self._lock:
            if not job.waiting:
                return False
            job.waiting = False
            self._waiting -= 1
            return True

    def _finish(self, job: Job, outcome: Outcome) -> None:
        fn = job.claim()
        if fn is None:
            return  # already answered (e.g. TIMEOUT while it waited)
        self.count("ok" if outcome[0] else outcome[1]["code"])
        try:
            fn(outcome)
        except Exception:  # noqa: BLE001 -- a failed reply must not kill the pool thread
            _log.exception("request %s: sending the reply failed", job.request_id)

    def _watch(self) -> None:
        while True:
            with self._cond:
                if self._stopping:
                    return
                now = time.monotonic()
                expired = []
                while self._heap and (self._heap[0][0] <= now or self._heap[0][2].done):
                    expired.append(heapq.heappop(self._heap)[2])
                if not expired:
                    timeout = self._heap[0][0] - now if self._heap else None
                    self._cond.wait(timeout)
                    continue
            for job in expired:
                # only jobs still waiting: a worker's slot times out its own job
                if self._dequeued(job):
                    self._finish(job, _waited_too_long(job))

    def _spawn(self, i: int) -> tuple[Any, Any]:
        parent, child = self._ctx.Pipe()
        proc = self._ctx.Process(target=worker_main, name=f"arduinobot-worker-{i}",
                                 args=(child, self.spec, logging.getLogger().level),
                                 daemon=True)
        proc.start()
        child.close()
        try:
            msg = parent.recv()
        except EOFError:
            proc.join(1.0)
            raise PoolStartError(f"worker {i} exited while starting "
                                 f"(exit code {proc.exitcode})") from None
        if msg[0] != "ready":
            proc.join(1.0)
            raise PoolStartError(f"worker {i} could not start: {msg[1]}")
        with self._lock:
            self._pids[i], self._procs[i] = msg[1], proc
        _log.debug("worker %d ready (pid %d)", i, msg[1])
        return proc, parent

    def _slot(self, i: int, ready: threading.Event, failures: list[str]) -> None:
        try:
            proc, conn = self._spawn(i)
        except PoolStartError as e:
            failures.append(str(e))
            ready.set()
            return
        ready.set()
        while True:
            job = self._queue.get()
            if job is not None and self._dequeued(job) and \
                    job.deadline <= time.monotonic():
                self._finish(job, _waited_too_long(job))
                continue
            if job is None or self._stopping:
                if job is not None:
                    self._finish(job, error("INTERNAL", "the service is shutting down"))
                if proc.is_alive():
                    conn.send(None)
                proc.join(2.0)
                return
            if job.done:
                continue
            with self._lock:
                self._busy[i] = job
            replace = False
            try:
                conn.send((job.request_id, job.kind, job.data))
                remaining = job.deadline - time.monotonic()
                if conn.poll(max(remaining, 0.0)):
                    msg = conn.recv()
                    self._finish(job, (True, msg[2]) if msg[1] == "ok" else error(
                        msg[2], msg[3], **{**msg[4], "request_id": job.request_id}))
                else:
                    replace = True
                    self.count("timeouts_in_worker")
                    self._finish(job, error("TIMEOUT", "the request's deadline passed "
                                            "while a worker was on it",
                                            request_id=job.request_id))
            except (EOFError, OSError, BrokenPipeError):
                replace = True
                proc.join(1.0)
                code = proc.exitcode
                how = (f"signal {signal.Signals(-code).name}" if code is not None and code < 0
                       else f"exit code {code}")
                with self._lock:
                    self._pids[i] = None
                if not self._stopping:
                    self.count("worker_crashes")
                    _log.error("worker %d (pid %s) died (%s) on request %s; replacing it",
                               i, proc.pid, how, job.request_id)
                self._finish(job, error("INTERNAL", "the service is shutting down"
                                        if self._stopping else
                                        f"the worker process died ({how}) while planning "
                                        "this request; it has been replaced",
                                        request_id=job.request_id, worker_exit=how))
            finally:
                with self._lock:
                    self._busy[i] = None
            if replace and not self._stopping:
                if proc.is_alive():
                    proc.kill()
                proc.join(2.0)
                conn.close()
                try:
                    proc, conn = self._spawn(i)
                    self.count("worker_restarts")
                except PoolStartError:
                    _log.exception("worker %d could not be replaced; its slot is closed", i)
                    with self._lock:
                        self._pids[i] = None
                    return
