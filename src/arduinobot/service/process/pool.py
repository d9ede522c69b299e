"""A pool of warm worker processes with a bounded queue, deadlines, a memory cap and
exactly one reply per job.

Workers are forked from a zygote that holds the built model (:mod:`arduinobot.service.process.zygote`), so a
worker that dies or is killed is replaced in milliseconds, before the next job needs it.
One parent thread per slot feeds its worker over a socket and watches it
(:mod:`arduinobot.service.process.slot`); a job that arrives while a worker waits idle (and none queues) is
sent to that worker by the submitting thread itself, one thread wake fewer before the
worker has it:

- past the job's deadline the worker is killed (it may be stuck in native code, or
  stopped) and the job gets TIMEOUT;
- past the memory cap (its resident set, polled while it works) it is killed and the job
  gets RESOURCE_LIMIT;
- if it dies on its own, the job gets INTERNAL (``details.worker_exit`` says how), unless
  it died before taking the job: then the job goes back to the head of the queue (at
  most once per worker);
- an idle worker's death is reported by the zygote at once and the slot re-forks.

This module keeps the jobs: the queue, the waiting jobs' deadlines, the counters. A
queued job's reply is sent from the pool's threads (or :meth:`WorkerPool.close`'s
caller), never from Zenoh's; only :meth:`WorkerPool.submit`'s refusals are sent at once.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import multiprocessing as mp
import threading
import time
import weakref
from collections import Counter, deque
from typing import Any

from arduinobot.contract.codes import Code
from arduinobot.service.messages import Outcome, Success
from arduinobot.service.process.job import Job, failure, shutting_down, timed_out
from arduinobot.service.process.slot import Slot, Workers, rss_bytes
from arduinobot.service.process.worker import DescriptionSpec
from arduinobot.service.process.zygote import ZygoteError

__all__ = ["Job", "Outcome", "PoolStartError", "WorkerPool", "rss_bytes"]

_log = logging.getLogger(__name__)

#: the deadline heap is rebuilt without the entries of jobs that left the queue once it
#: holds more than this many beyond the waiting ones
_HEAP_SLACK = 64


class PoolStartError(RuntimeError):
    """The workers could not load the description or warm up."""


class WorkerPool:
    """``workers`` warm processes forked from one zygote that built the model once.

    Args:
        spec: how the zygote loads the description.
        workers: number of worker processes (>= 1).
        queue_size: jobs that may wait for a free worker; more are refused (BUSY).
        memory_cap: a worker's largest resident set [bytes]; past it the worker is
            killed and its job answered RESOURCE_LIMIT (None: no cap).
    """

    def __init__(self, spec: DescriptionSpec, *, workers: int, queue_size: int,
                 memory_cap: int | None = None) -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        if memory_cap is not None and memory_cap <= 0:
            raise ValueError("memory_cap must be > 0 bytes")
        self.workers, self.queue_size = workers, queue_size
        self.memory_cap = memory_cap
        # the zygote's forkserver (see arduinobot.service.process.zygote): the planner's imports (trimesh,
        # toppra, OMPL: ~2 s) run in it while the caller loads the description, not again
        # in the zygote
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["arduinobot.service.process.worker", "arduinobot.service.plan.handlers",
                                  "arduinobot.planner.planning.pipeline"])
        from multiprocessing import forkserver
        forkserver.ensure_running()
        self.counters: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self._jobs: deque[Job] = deque()  # the waiting jobs, and only they
        # (deadline, seq, job) of the waiting jobs, the job by weak reference: a job that
        # left the queue is answered and freed (with its payload and its query) at once,
        # not when its deadline reaches the top. Dead entries go at the top, or all at
        # once past _HEAP_SLACK.
        self._heap: list[tuple[float, int, weakref.ref[Job]]] = []
        self._seq = itertools.count()
        self._workers = Workers(ctx, spec, self._cond, count=self.count)
        self._slots = [Slot(i, self._workers, self) for i in range(workers)]
        self._busy: dict[int, Job] = {}  # slot index -> its job
        # slots waiting in next_job with a live worker: a job submitted while one waits
        # and none queues is sent to its worker by the submitting thread (one thread
        # wake fewer before the worker has it)
        self._idle: list[Slot] = []
        self._service_time = 0.5  # moving average of a job's time in a worker [s]
        self.stopping = False
        self.grace_end = 0.0  # when running jobs stop getting time after close [monotonic s]
        self._threads: list[threading.Thread] = []

    # -- lifecycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Build the model once (in the zygote), fork every worker, start serving.

        Raises:
            PoolStartError: the description could not be loaded (the message says why).
        """
        try:
            self._workers.start()
            for slot in self._slots:
                slot.worker = self._workers.fork()
        except ZygoteError as e:
            self.close()
            raise PoolStartError(str(e)) from None
        targets = [(s.run, f"pool-slot-{s.index}") for s in self._slots]
        for target, name in [*targets, (self._watch, "pool-deadlines")]:
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)

    def close(self, *, grace: float = 2.0) -> None:
        """Refuse new jobs and answer waiting ones SHUTTING_DOWN, give running ones
        ``grace`` seconds [s] (then SHUTTING_DOWN too), stop the workers."""
        with self._cond:
            self.stopping = self._workers.stopping = True
            self.grace_end = time.monotonic() + grace
            drained = list(self._jobs)
            for j in drained:
                j.waiting = False
            self._jobs.clear()
            self._heap.clear()
            self._cond.notify_all()
        for job in drained:
            self.finish(job, shutting_down(job))
        for t in self._threads:
            t.join(timeout=grace + 3.0)
        self._workers.close()

    def __enter__(self) -> WorkerPool:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- submitting --------------------------------------------------------------------
    def submit(self, job: Job) -> None:
        """Queue a job, or answer it at once: BUSY when the queue is full (with
        ``details.retry_after`` [s]), SHUTTING_DOWN once :meth:`close` has begun.

        A ``frames`` job (a kept-scene attach's or detach's link poses: a millisecond's
        work) goes to the head of the queue, full or not: the scene's applies are made one
        at a time, so at most one of them waits, and a scene change is not refused for
        the plans in the queue."""
        self.count("received")
        slot = None
        # (and a moving arm's rest re-checked after a scene change: its stop waits on it)
        urgent = job.kind in ("frames", "recheck")
        with self._cond:
            stopping = self.stopping
            full = len(self._jobs) >= self.queue_size and not urgent
            if not (stopping or full):
                if self._idle and not self._jobs:
                    slot = self._idle.pop()
                    job.handoff = threading.Event()
                    slot.handed = job
                else:
                    self._enqueue(job, first=urgent)
            retry = max(0.05, self._service_time / self.workers)
        if slot is not None:
            slot.dispatch(job)
            # the slot's thread wakes once its worker has the job, not before: a thread
            # woken earlier would take the GIL from the send on its way
            with self._cond:
                self._cond.notify_all()
            return
        if stopping:
            self.finish(job, shutting_down(job))
        elif full:
            self.finish(job, failure(
                job, Code.BUSY, f"all {self.workers} workers are busy and "
                f"{self.queue_size} requests are waiting; retry in about {retry:.2f} s or "
                "use another instance", workers=self.workers, queue_size=self.queue_size,
                retry_after=round(retry, 3)))

    def status(self) -> dict[str, Any]:
        """Live workers (pid, busy request), queue depth, counters and the load (busy
        workers plus waiting jobs, per worker: clients pick the least loaded instance by
        it), JSON-ready."""
        with self._lock:
            workers = [{"pid": s.live_pid(),
                        "busy": None if s.index not in self._busy
                        else self._busy[s.index].request_id}
                       for s in self._slots]
            counters = dict(self.counters)
            depth = len(self._jobs)
            load = (len(self._busy) + depth) / self.workers
        return {"workers": workers, "queue_depth": depth, "queue_size": self.queue_size,
                "memory_cap": self.memory_cap, "zygote": self._workers.zygote_pid,
                "counters": counters, "load": load}

    def count(self, key: str) -> None:
        with self._lock:
            self.counters[key] += 1

    def held(self) -> dict[str, int]:
        """What the pool holds now: queued jobs, deadline-heap entries, running jobs (a
        debug probe's numbers, see :mod:`arduinobot.service.process.memtrace`)."""
        with self._lock:
            return {"queued": len(self._jobs), "heap": len(self._heap),
                    "running": len(self._busy)}

    # -- what the slots call (arduinobot.service.process.slot.JobQueue) -------------------------------------
    def next_job(self, slot: Slot) -> Job | None:
        """The job handed to ``slot`` (already sent to its worker), else the next waiting
        job, or None when stopping or the slot's worker has died."""
        with self._cond:
            try:
                while True:
                    if slot.handed is not None:
                        job, slot.handed = slot.handed, None
                        return job
                    if self.stopping or slot.live_pid() is None:
                        return None
                    if self._jobs:
                        job = self._jobs.popleft()
                        job.waiting = False
                        self._drop_stale()
                        return job
                    if slot not in self._idle:
                        self._idle.append(slot)
                    self._cond.wait()
            finally:
                if slot in self._idle:
                    self._idle.remove(slot)

    def requeue(self, job: Job) -> None:
        """Put a job its worker never took back at the head of the queue (to be sent
        again, by the slot that takes it)."""
        with self._cond:
            job.handoff, job.handoff_error = None, None
            self._enqueue(job, first=True)

    def set_busy(self, slot: Slot, job: Job | None) -> None:
        with self._lock:
            if job is None:
                self._busy.pop(slot.index, None)
            else:
                self._busy[slot.index] = job

    def served(self, seconds: float) -> None:
        """A job took ``seconds`` [s] in a worker (for BUSY's retry hint)."""
        with self._lock:
            self._service_time += 0.2 * (seconds - self._service_time)

    def finish(self, job: Job, outcome: Outcome) -> None:
        """Answer ``job`` unless it was answered already (e.g. TIMEOUT while it waited)."""
        fn = job.claim()
        if fn is None:
            return
        self.count("ok" if isinstance(outcome, Success) else outcome.code.value)
        try:
            fn(outcome)
        except Exception:  # noqa: BLE001 -- a failed reply must not kill the pool thread
            _log.exception("request %s: sending the reply failed", job.request_id)

    # -- the queue and the waiting jobs' deadlines -----------------------------------
    def _enqueue(self, job: Job, *, first: bool) -> None:
        """(with the condition held)"""
        job.waiting = True
        if first:
            self._jobs.appendleft(job)
        else:
            self._jobs.append(job)
        heapq.heappush(self._heap, (job.deadline, next(self._seq), weakref.ref(job)))
        self._cond.notify_all()

    def _drop_stale(self) -> None:
        """Forget the heap entries of jobs no longer waiting once they are many (with
        the condition held), so the heap stays as small as the queue."""
        if len(self._heap) > len(self._jobs) + _HEAP_SLACK:
            self._heap = [e for e in self._heap if _waiting(e)]
            heapq.heapify(self._heap)

    def _watch(self) -> None:
        while self._answer_expired():
            pass

    def _answer_expired(self) -> bool:
        """Wait until waiting jobs pass their deadline and answer them TIMEOUT; False
        once stopping. (Its own frame, so the watcher holds no answered job while it
        waits.)"""
        with self._cond:
            while True:
                if self.stopping:
                    return False
                now = time.monotonic()
                expired = []
                while self._heap and (self._heap[0][0] <= now or not _waiting(self._heap[0])):
                    job = heapq.heappop(self._heap)[2]()
                    if job is not None and job.waiting:  # (a slot times out its own job)
                        job.waiting = False
                        self._jobs.remove(job)  # O(queue_size): it holds no answered job
                        expired.append(job)
                if expired:
                    break
                self._cond.wait(self._heap[0][0] - now if self._heap else None)
        for job in expired:
            self.finish(job, timed_out(job, "while it waited for a worker"))
        return True


def _waiting(entry: tuple[float, int, weakref.ref[Job]]) -> bool:
    job = entry[2]()
    return job is not None and job.waiting
