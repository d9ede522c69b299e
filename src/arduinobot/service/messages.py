"""What a job ends with, and what the service's processes say to each other.

A job's :data:`Outcome` is a :class:`Success` (the reply, already encoded by the worker)
or a :class:`Failure` (a coded error). The messages below cross the pipes and sockets
between the pool (:mod:`arduinobot.service.process.pool`, :mod:`arduinobot.service.process.slot`), the zygote
(:mod:`arduinobot.service.process.zygote`) and the workers (:mod:`arduinobot.service.process.worker`), pickled:

- pool -> worker: :class:`JobMsg`, then :class:`Stop`;
- worker -> pool: on receipt, the job's number in its :class:`TakenMark` (memory, not a
  message); :class:`Deadline` once the request is valid, then :class:`Done` with the
  outcome;
- pool -> zygote: :class:`Fork`, then :class:`Stop`;
- zygote -> pool: :class:`Ready` (or :class:`StartFailed`) once, then :class:`Forked`
  (followed by the worker socket's fd and its TakenMark's) per fork and :class:`Exited`
  per worker that ends.
"""

from __future__ import annotations

import mmap
import os
import struct
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any, Literal

from arduinobot.contract.codes import Code
from arduinobot.contract.errors import PlanningError
from arduinobot.contract.wire import error_json


@dataclass(frozen=True)
class Success:
    """A job's reply: the JSON body the worker encoded (``request_id`` included), and
    for a task to run, the execute request the worker built for the serving process to
    send (:mod:`arduinobot.service.task.task_service`)."""

    body: bytes
    execute: bytes | None = None


@dataclass(frozen=True)
class Failure:
    """A job's coded error, as the wire's ``{"error": {code, message, details}}``."""

    code: Code
    message: str
    details: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, e: PlanningError, **details: Any) -> Failure:
        """The failure ``e`` codes, with ``details`` added to its own."""
        return cls(e.code, e.message, {**e.details, **details})

    def to_json(self) -> dict[str, Any]:
        return error_json(self.code, self.message, self.details)


#: what a job ends with
Outcome = Success | Failure
#: what the worker pool does
JobKind = Literal["plan", "fk", "ik", "check", "task", "frames", "recheck"]
#: submits a job to the service's worker pool: ``submit(kind, data, respond)``
#: (:meth:`arduinobot.service.server.PlannerService.submit`); ``respond`` gets its one outcome
Submit = Callable[[JobKind, Mapping[str, Any], Callable[[Outcome], None]], None]
#: submits a plan job (a valid plan request dict) to the pool: ``submit_plan(data,
#: respond)``; ``respond`` gets its one outcome, from a pool thread
SubmitPlan = Callable[[dict[str, Any], Callable[[Outcome], None]], None]


def outcome_of(submit: Submit, kind: JobKind, data: Mapping[str, Any]) -> Outcome:
    """Submit a job and wait for its outcome: the pool answers every job exactly once
    (done, refused, or TIMEOUT past its deadline), so this returns."""
    done = threading.Event()
    box: list[Outcome] = []

    def respond(outcome: Outcome) -> None:
        box.append(outcome)
        done.set()
    submit(kind, data, respond)
    done.wait()
    return box[0]


@dataclass(frozen=True)
class Stop:
    """Finish the current job (if any), then end."""


@dataclass(frozen=True)
class JobMsg:
    """A job for a worker. ``payload`` is the raw request (decoded and validated by the
    worker) or an already valid dict; ``base_deadline`` is the arrival time plus the
    service's timeout [s, :func:`time.monotonic`: the same clock in every process]."""

    job_id: str
    kind: str
    payload: bytes | str | Mapping[str, Any]
    base_deadline: float
    #: the kept scene the request is answered against (:class:`arduinobot.scene.state.SceneSnapshot`),
    #: or :data:`HELD_SCENE`: the one this worker was sent last (a kept scene of 20
    #: primitives is 2.7 KB pickled, ~60 us to pickle and unpickle: sent once per worker
    #: and revision, not with every job)
    scene: Any = None
    #: the job's number on its slot (counting from 1), what the worker marks as taken
    seq: int = 0


#: :attr:`JobMsg.scene` when the worker already holds the job's scene
HELD_SCENE = "held"


class TakenMark:
    """The number of the last job a worker has received, in 8 bytes of memory it shares
    with its slot: a worker that dies before marking a job did not die of it (the slot
    gives the job to another worker).

    Memory, not a message: a message on the socket woke the slot's thread as the worker
    started on the job, costing the worker ~50 us on every request's path (the thread
    woken on its core); the slot reads the mark only once the worker has died.
    """

    SIZE = 8

    def __init__(self, fd: int) -> None:
        """Map the shared memory ``fd`` (the caller closes the fd; the map stays)."""
        self._mm = mmap.mmap(fd, self.SIZE)

    @classmethod
    def create(cls) -> tuple[TakenMark, int]:
        """A new mark (0: nothing taken) and its fd, to hand to the other process."""
        fd = os.memfd_create("arduinobot-taken", os.MFD_CLOEXEC)
        os.ftruncate(fd, cls.SIZE)
        return cls(fd), fd

    def mark(self, seq: int) -> None:
        struct.pack_into("<Q", self._mm, 0, seq)

    @property
    def seq(self) -> int:
        """The number of the last job marked taken."""
        return int(struct.unpack_from("<Q", self._mm, 0)[0])


@dataclass(frozen=True)
class Deadline:
    """The request is valid; it must be answered by ``deadline`` [monotonic s] (plans
    add their planning_time)."""

    job_id: str
    deadline: float


@dataclass(frozen=True)
class Done:
    """The job's outcome; ``trace``: the worker's stamps when tracing the hop
    (:data:`arduinobot.service.hoptrace.WORKER_STAMPS`), else empty."""

    job_id: str
    outcome: Outcome
    trace: tuple[float, ...] = ()


@dataclass(frozen=True)
class Fork:
    """Fork a warm worker; answer :class:`Forked` with the same ``token``."""

    token: int


@dataclass(frozen=True)
class Ready:
    """The zygote built the model."""


@dataclass(frozen=True)
class StartFailed:
    """The zygote could not build the model (``message`` says why)."""

    message: str


@dataclass(frozen=True)
class Forked:
    """A worker was forked for ``token``; its socket's fd follows on the pipe."""

    token: int
    pid: int


@dataclass(frozen=True)
class Exited:
    """A worker ended; ``how`` as ``"signal SIGKILL"`` or ``"exit code 1"``."""

    pid: int
    how: str


def receive(conn: Connection) -> Any | None:
    """The next message on ``conn``, or None once the other side said :class:`Stop` or
    closed its end (the one way every loop over a pipe ends)."""
    try:
        msg = conn.recv()
    except EOFError:
        return None
    return None if isinstance(msg, Stop) else msg
