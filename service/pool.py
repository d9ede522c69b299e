"""A pool of warm worker processes with a bounded queue, deadlines, a memory cap and
exactly one reply per job.

Workers are forked from a zygote that holds the built model (:mod:`service.zygote`), so a
worker that dies or is killed is replaced in milliseconds, before the next job needs it.
One parent thread per slot feeds its worker over a socket and watches it:

- past the job's deadline the worker is killed (it may be stuck in native code, or
  stopped) and the job gets TIMEOUT;
- past the memory cap (its resident set, polled while it works) it is killed and the job
  gets RESOURCE_LIMIT;
- if it dies on its own, the job gets INTERNAL (``details.worker_exit`` says how), unless
  it died before taking the job: then the job goes back to the head of the queue, once;
- an idle worker's death is reported by the zygote at once and the slot re-forks.

Past ``queue_size`` waiting jobs, ``submit`` refuses at once (BUSY, with a retry hint).
On :meth:`close`, waiting jobs get SHUTTING_DOWN at once and running ones ``grace``
seconds to finish. Replies are sent from these threads, never from Zenoh's.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import multiprocessing as mp
import os
import signal
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from .worker import DEFAULT_PLANNING_TIME, DescriptionSpec, job_deadline
from .zygote import WorkerProcess, Zygote, ZygoteError

_log = logging.getLogger(__name__)

#: ``(True, reply JSON bytes)`` or ``(False, {"code", "message", "details"})``.
Outcome = tuple[bool, Any]

#: how often a busy worker's reply, memory and the shutdown grace are looked at [s]
_POLL = 0.05
_PAGE = os.sysconf("SC_PAGE_SIZE")


class PoolStartError(RuntimeError):
    """The workers could not load the description or warm up."""


@dataclass(eq=False)
class Job:
    """One request in flight. ``respond`` is called exactly once (first outcome wins),
    then dropped, so whatever it holds (a Zenoh query) is released.

    ``payload`` is the raw request (validated by the worker) or an already valid dict;
    ``base_deadline`` is arrival + the service's timeout [monotonic s]. ``deadline`` is
    provisional (plans: + the default planning_time) until the worker has read the
    request's own planning_time.
    """

    kind: str
    payload: bytes | str | Mapping[str, Any]
    request_id: str
    base_deadline: float
    respond: Callable[[Outcome], None] | None
    deadline: float = field(init=False)
    waiting: bool = False  # in the queue, counted against queue_size
    retried: bool = False  # handed back once after a worker died before taking it
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def __post_init__(self) -> None:
        if isinstance(self.payload, Mapping):
            self.deadline = job_deadline(self.kind, self.payload, self.base_deadline)
        else:
            self.deadline = self.base_deadline + (
                DEFAULT_PLANNING_TIME if self.kind == "plan" else 0.0)

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


def rss_bytes(pid: int) -> int:
    """Resident set size of process ``pid`` [bytes] (0 once it is gone)."""
    try:
        with open(f"/proc/{pid}/statm", "rb") as f:
            return int(f.read().split()[1]) * _PAGE
    except (OSError, IndexError, ValueError):
        return 0


@dataclass(eq=False)
class _Slot:
    index: int
    worker: WorkerProcess | None = None
    busy: Job | None = None


Stop = Literal["deadline", "memory", "shutdown"]


class WorkerPool:
    """``workers`` warm processes forked from one zygote that built the model once.

    Args:
        spec: how the zygote loads the description.
        workers: number of worker processes (>= 1).
        queue_size: jobs that may wait for a free worker; more are refused (BUSY).
        start_method: how the zygote is started: ``forkserver`` (default; the planner's
            imports are preloaded) or ``spawn``.
        memory_cap: a worker's largest resident set [bytes]; past it the worker is
            killed and its job answered RESOURCE_LIMIT (None: no cap).
    """

    def __init__(self, spec: DescriptionSpec, *, workers: int, queue_size: int,
                 start_method: Literal["forkserver", "spawn"] = "forkserver",
                 memory_cap: int | None = None) -> None:
        if workers < 1 or queue_size < 0:
            raise ValueError("workers must be >= 1 and queue_size >= 0")
        if memory_cap is not None and memory_cap <= 0:
            raise ValueError("memory_cap must be > 0 bytes")
        self.spec, self.workers, self.queue_size = spec, workers, queue_size
        self.memory_cap = memory_cap
        self._ctx = mp.get_context(start_method)
        if start_method == "forkserver":
            # the planner's imports (trimesh, toppra, OMPL: ~2 s) run in the forkserver
            # while the caller loads the description, not again in the zygote
            self._ctx.set_forkserver_preload(["service.worker", "planner.pipeline"])
            from multiprocessing import forkserver
            forkserver.ensure_running()
        self.counters: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self._jobs: deque[Job] = deque()
        self._waiting = 0
        self._heap: list[tuple[float, int, Job]] = []
        self._seq = itertools.count()
        self._slots = [_Slot(i) for i in range(workers)]
        self._live: set[int] = set()  # pids of the slots' current workers
        self._exits: dict[int, str] = {}  # ... that ended: how
        self._service_time = 0.5  # moving average of a job's time in a worker [s]
        self._stopping = False
        self._grace_end = 0.0
        self._threads: list[threading.Thread] = []
        self._zygote: Zygote | None = None
        self._zygote_lock = threading.Lock()

    # -- lifecycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Build the model once (in the zygote), fork every worker, start serving.

        Raises:
            PoolStartError: the description could not be loaded (the message says why).
        """
        try:
            self._zygote = self._new_zygote()
            for slot in self._slots:
                self._adopt(slot, self._zygote.fork())
        except ZygoteError as e:
            self.close()
            raise PoolStartError(str(e)) from None
        for slot in self._slots:
            self._spawn_thread(self._run_slot, slot, name=f"pool-slot-{slot.index}")
        self._spawn_thread(self._watch, name="pool-deadlines")

    def close(self, *, grace: float = 2.0) -> None:
        """Refuse new jobs and answer waiting ones SHUTTING_DOWN, give running ones
        ``grace`` seconds [s] (then SHUTTING_DOWN too), stop the workers."""
        with self._cond:
            self._stopping = True
            self._grace_end = time.monotonic() + grace
            drained = [j for j in self._jobs if j.waiting]
            for j in drained:
                j.waiting = False
            self._jobs.clear()
            self._waiting = 0
            self._cond.notify_all()
        for job in drained:
            self._finish(job, _shutting_down(job))
        for t in self._threads:
            t.join(timeout=grace + 3.0)
        if self._zygote is not None:
            self._zygote.close()

    def __enter__(self) -> WorkerPool:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- submitting --------------------------------------------------------------------
    def submit(self, job: Job) -> None:
        """Queue a job, or answer it at once: BUSY when the queue is full (with
        ``details.retry_after`` [s]), SHUTTING_DOWN once :meth:`close` has begun."""
        self.count("received")
        with self._cond:
            stopping, full = self._stopping, self._waiting >= self.queue_size
            if not (stopping or full):
                self._waiting += 1
                job.waiting = True
                self._jobs.append(job)
                heapq.heappush(self._heap, (job.deadline, next(self._seq), job))
                self._cond.notify_all()
            retry = max(0.05, self._service_time / self.workers)
        if stopping:
            self._finish(job, _shutting_down(job))
        elif full:
            self._finish(job, error(
                "BUSY", f"all {self.workers} workers are busy and {self.queue_size} "
                f"requests are waiting; retry in about {retry:.2f} s or use another "
                "instance", workers=self.workers, queue_size=self.queue_size,
                retry_after=round(retry, 3), request_id=job.request_id))

    def status(self) -> dict[str, Any]:
        """Live workers (pid, busy request), queue depth and counters, JSON-ready."""
        with self._lock:
            workers = [{"pid": self._live_pid(s),
                        "busy": None if s.busy is None else s.busy.request_id}
                       for s in self._slots]
            counters = dict(self.counters)
            depth = self._waiting
        return {"workers": workers, "queue_depth": depth, "queue_size": self.queue_size,
                "memory_cap": self.memory_cap,
                "zygote": None if self._zygote is None else self._zygote.pid,
                "counters": counters}

    def count(self, key: str) -> None:
        with self._lock:
            self.counters[key] += 1

    # -- the zygote and its workers --------------------------------------------------
    def _new_zygote(self) -> Zygote:
        z = Zygote(self._ctx, self.spec, on_exit=self._on_exit, on_lost=self._on_lost)
        z.start()
        return z

    def _on_exit(self, pid: int, how: str) -> None:
        with self._cond:
            if pid in self._live:
                self._exits[pid] = how
                self._cond.notify_all()

    def _on_lost(self) -> None:
        if not self._stopping:
            _log.error("the worker zygote ended; starting a new one (the model is built "
                       "again)")

    def _live_pid(self, slot: _Slot) -> int | None:
        w = slot.worker
        return None if w is None or w.pid in self._exits else w.pid

    def _adopt(self, slot: _Slot, worker: WorkerProcess) -> None:
        with self._lock:
            slot.worker = worker
            self._live.add(worker.pid)
        _log.debug("worker %d ready (pid %d)", slot.index, worker.pid)

    def _retire(self, slot: _Slot, *, kill: bool) -> str | None:
        """Drop the slot's worker (killing it first if asked); how it ended if known."""
        w = slot.worker
        if w is None:
            return None
        if kill:
            try:
                os.kill(w.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass  # it died on its own meanwhile
        how = self._await_exit(w.pid, 0.0 if kill else 1.0)
        w.conn.close()
        with self._lock:
            slot.worker = None
            self._live.discard(w.pid)
            self._exits.pop(w.pid, None)
        return how

    def _await_exit(self, pid: int, timeout: float) -> str | None:
        with self._cond:
            self._cond.wait_for(lambda: pid in self._exits, timeout)
            return self._exits.get(pid)

    def _replace(self, slot: _Slot) -> bool:
        """Give the slot a fresh worker (re-starting the zygote if it is gone); False if
        the pool is stopping."""
        while not self._stopping:
            try:
                self._adopt(slot, self._zygote.fork())  # type: ignore[union-attr]
                self.count("worker_restarts")
                return True
            except ZygoteError as e:
                _log.warning("worker %d: %s", slot.index, e)
            with self._zygote_lock:
                if self._stopping or (self._zygote is not None and self._zygote.alive):
                    continue
                try:
                    self._zygote.close(timeout=0.5)  # type: ignore[union-attr]
                    self._zygote = self._new_zygote()
                    self.count("zygote_restarts")
                except ZygoteError:
                    _log.exception("the worker zygote could not be restarted; retrying")
                    time.sleep(1.0)
        return False

    # -- the slots ---------------------------------------------------------------------
    def _spawn_thread(self, target: Callable[..., None], *args: Any, name: str) -> None:
        t = threading.Thread(target=target, args=args, name=name, daemon=True)
        t.start()
        self._threads.append(t)

    def _next_job(self, slot: _Slot) -> Job | None:
        """The next waiting job, or None when stopping or the slot's worker has died."""
        with self._cond:
            while True:
                if self._stopping or self._live_pid(slot) is None:
                    return None
                while self._jobs:
                    job = self._jobs.popleft()
                    if job.waiting:
                        job.waiting = False
                        self._waiting -= 1
                        return job
                self._cond.wait()

    def _run_slot(self, slot: _Slot) -> None:
        while True:
            if slot.worker is not None and self._live_pid(slot) is None and \
                    not self._stopping:
                how = self._retire(slot, kill=False)
                self.count("worker_crashes")
                _log.error("idle worker %d died (%s); replacing it", slot.index, how)
            if slot.worker is None and not self._replace(slot):
                return
            job = self._next_job(slot)
            if job is None:
                if self._stopping:
                    self._stop_worker(slot)
                    return
                continue
            if job.deadline <= time.monotonic():
                self._finish(job, _timed_out(job, "while it waited for a worker"))
                continue
            self._run(slot, slot.worker, job)  # type: ignore[arg-type]

    def _stop_worker(self, slot: _Slot) -> None:
        w = slot.worker
        if w is None:
            return
        try:
            w.conn.send(None)
        except OSError:
            pass  # already gone
        self._retire(slot, kill=False)

    def _run(self, slot: _Slot, w: WorkerProcess, job: Job) -> None:
        with self._lock:
            slot.busy = job
        t0 = time.monotonic()
        taken, outcome, stop = False, None, None
        try:
            w.conn.send((job.request_id, job.kind, job.payload, job.base_deadline))
            while outcome is None:
                stop = self._why_stop(job, w)
                if stop is not None:
                    break
                if not w.conn.poll(min(_POLL, max(0.0, job.deadline - time.monotonic()))):
                    continue
                msg = w.conn.recv()
                if msg[0] == "taken":
                    taken = True
                    continue
                if msg[0] == "deadline":
                    job.deadline = msg[2]
                    continue
                outcome = (True, msg[2]) if msg[1] == "ok" else error(
                    msg[2], msg[3], **{**msg[4], "request_id": job.request_id})
        except (EOFError, OSError):
            pass  # the worker died: neither an outcome nor a stop, handled below
        finally:
            with self._lock:
                slot.busy = None
        if outcome is not None:
            with self._lock:
                self._service_time += 0.2 * (time.monotonic() - t0 - self._service_time)
            self._finish(job, outcome)
            return
        if stop is not None:
            self._retire(slot, kill=True)
            self.count({"deadline": "timeouts_in_worker", "memory": "memory_kills",
                        "shutdown": "shutdown_kills"}[stop])
            self._finish(job, _stopped(job, stop, self.memory_cap))
            return
        how = self._retire(slot, kill=False)
        if self._stopping:
            self._finish(job, _shutting_down(job))
            return
        self.count("worker_crashes")
        if not taken and not job.retried:
            # it died before receiving this job (killed while idle, the report not yet
            # in): the job is not the cause, so it goes first to the next worker
            _log.error("worker %d died (%s) before taking request %s; re-dispatching it",
                       slot.index, how, job.request_id)
            self.count("redispatched")
            job.retried = True
            with self._cond:
                job.waiting = True
                self._waiting += 1
                self._jobs.appendleft(job)
                heapq.heappush(self._heap, (job.deadline, next(self._seq), job))
                self._cond.notify_all()
            return
        _log.error("worker %d died (%s) on request %s; replacing it", slot.index, how,
                   job.request_id)
        self._finish(job, error("INTERNAL", f"the worker process died ({how or 'unknown'}) "
                                "while planning this request; it has been replaced",
                                request_id=job.request_id, worker_exit=how))

    def _why_stop(self, job: Job, w: WorkerProcess) -> Stop | None:
        now = time.monotonic()
        if self._stopping and now >= self._grace_end:
            return "shutdown"
        if now >= job.deadline:
            return "deadline"
        if self.memory_cap is not None and rss_bytes(w.pid) > self.memory_cap:
            return "memory"
        return None

    # -- replies and the waiting jobs' deadlines -----------------------------------
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
                while self._heap and (self._heap[0][0] <= now or not self._heap[0][2].waiting):
                    job = heapq.heappop(self._heap)[2]
                    if job.waiting:  # a worker's slot times out its own job
                        job.waiting = False
                        self._waiting -= 1
                        expired.append(job)
                if not expired:
                    self._cond.wait(self._heap[0][0] - now if self._heap else None)
                    continue
            for job in expired:
                self._finish(job, _timed_out(job, "while it waited for a worker"))


def _timed_out(job: Job, when: str) -> Outcome:
    return error("TIMEOUT", f"the request's deadline passed {when}",
                 request_id=job.request_id)


def _shutting_down(job: Job) -> Outcome:
    return error("SHUTTING_DOWN", "this instance is shutting down; retry (another "
                 "instance, if any, takes the request)", request_id=job.request_id)


def _stopped(job: Job, stop: Stop, cap: int | None) -> Outcome:
    if stop == "deadline":
        return _timed_out(job, "while a worker was on it (the worker was replaced)")
    if stop == "memory":
        return error("RESOURCE_LIMIT", f"the request needed more than the worker memory "
                     f"cap of {(cap or 0) // 2**20} MiB (the worker was replaced)",
                     request_id=job.request_id, memory_cap=cap)
    return _shutting_down(job)
