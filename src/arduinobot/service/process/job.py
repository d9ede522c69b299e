"""One request in the worker pool, and the coded failures the pool itself answers with."""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from arduinobot.contract.codes import Code
from arduinobot.service.messages import Failure, Outcome
from arduinobot.service.process.worker import job_deadline

#: why the pool stopped a worker in the middle of a job
Stop = Literal["deadline", "memory", "shutdown"]
#: what a request gets once its instance is stopping
SHUTTING_DOWN = ("this instance is shutting down; retry (another instance, if any, takes "
                 "the request)")


@dataclass(eq=False)
class Job:
    """One request in flight. ``respond`` is called exactly once (first outcome wins),
    then dropped, so whatever it holds (a Zenoh query) is released.

    ``payload`` and ``base_deadline``: as in :class:`~arduinobot.service.messages.JobMsg`.
    ``deadline`` is provisional (plans: + the default planning_time) until the worker has
    read the request's own planning_time.
    """

    kind: str
    payload: bytes | str | Mapping[str, Any]
    request_id: str
    base_deadline: float
    respond: Callable[[Outcome], None] | None
    #: the kept scene when the request arrived (a SceneSnapshot; plans and checks)
    scene: Any = None
    deadline: float = field(init=False)
    waiting: bool = False  # in the queue, counted against queue_size
    # times handed back after a worker died before taking it (at most once per worker:
    # all of them may have been killed while idle, their reports not yet in)
    redispatched: int = 0
    #: the hop's stamps by stage when tracing (:mod:`arduinobot.service.hoptrace`), else None
    trace: dict[str, float] | None = None
    #: set once the submitting thread has sent the job to an idle slot's worker itself
    #: (:meth:`arduinobot.service.process.slot.Slot.dispatch`); None for a job that went through the queue
    handoff: threading.Event | None = None
    #: why that send failed, if it failed for another reason than the worker's death
    handoff_error: str | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def __post_init__(self) -> None:
        valid = self.payload if isinstance(self.payload, Mapping) else {}
        self.deadline = job_deadline(self.kind, valid, self.base_deadline)

    def claim(self) -> Callable[[Outcome], None] | None:
        """Take the right to reply (once): the responder, or None if already taken."""
        with self._lock:
            fn, self.respond = self.respond, None
        return fn


def failure(job: Job, code: Code, message: str, **details: Any) -> Failure:
    """A coded failure for ``job`` (its request_id in the details)."""
    return Failure(code, message, {**details, "request_id": job.request_id})


def timed_out(job: Job, when: str) -> Failure:
    return failure(job, Code.TIMEOUT, f"the request's deadline passed {when}")


def shutting_down(job: Job) -> Failure:
    return failure(job, Code.SHUTTING_DOWN, SHUTTING_DOWN)


def stopped(job: Job, stop: Stop, cap: int | None) -> Failure:
    """The failure of a job whose worker the pool killed (``stop`` says why)."""
    if stop == "deadline":
        return timed_out(job, "while a worker was on it (the worker was replaced)")
    if stop == "memory":
        return failure(job, Code.RESOURCE_LIMIT, f"the request needed more than the worker "
                       f"memory cap of {(cap or 0) // 2**20} MiB (the worker was replaced)",
                       memory_cap=cap)
    return shutting_down(job)
