"""Following a stream of the service from the Python client: :meth:`PlannerClient.execute`
and :meth:`PlannerClient.task`, the CLI's ``task --remote`` and the ROS 2 task server.

One query on ``<prefix>/execute`` answers with a stream: ``started`` (the execution id,
its duration), ``progress`` every 0.1 s (and, when the kept scene changes while the arm
moves, ``changed``, ``stopped``, ``replanned``), then ``finished`` with the report (or a coded
error, e.g. ``PORT_ERROR`` with the last setpoint the arm took); one on ``<prefix>/task``
first answers ``planned``, then, executed, relays the same stream. :func:`follow` reads
both. While an execute runs, the client holds a liveliness token
``<prefix>/execute/client/<id>``: if this process dies or loses the network, the token
goes and the service stops the arm smoothly. Any client may cancel an execution by its
id (:func:`cancel_execution`).
"""

from __future__ import annotations

import json
import queue
import threading
import time
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import zenoh

from arduinobot.client.errors import MalformedReply, ServiceUnavailable
from arduinobot.contract.wire import JSON

#: How long the stream's query may last at most [s]: the execution's own length is not
#: known when a plan comes first, so the stream is bounded by this and watched for
#: silence instead (progress arrives every 0.1 s; see ``silence``).
STREAM_LIMIT = 24 * 3600.0

EventKind = Literal["started", "progress", "finished", "changed", "stopped", "replanned"]
#: every event kind an execution's stream carries: ``changed`` (a kept-scene change
#: re-checked the rest of the motion: the revision, the objects, ``certified``,
#: ``action``), ``stopped`` (stopped for it: the tick, ``stop_ms`` from the apply's
#: arrival to the first stop setpoint, where it came to rest), ``replanned`` (planned on
#: from there to the same goal: ``ok``, ``duration``)
EVENT_KINDS: tuple[str, ...] = ("started", "progress", "finished", "changed", "stopped",
                                "replanned")
#: a reply's JSON object, or the coded error of an error reply raised
#: (:func:`arduinobot.client.codec.decode_reply`): (reply, key, waited [s])
Decode = Callable[[zenoh.Reply, str, float], dict[str, Any]]


@dataclass(frozen=True)
class ExecutionEvent:
    """One reply of an execution's stream.

    Attributes:
        event: started, progress, finished, or one of a reaction to a scene change
            (changed, stopped, replanned: :data:`EVENT_KINDS`).
        execution: the execution's id (cancel it with it).
        duration: [s] of the trajectory (started); time: [s] since it began (progress).
        report: the execution report (finished): outcome, ticks, peaks, tracking errors.
        raw: the reply as received.
    """

    event: EventKind
    execution: str
    duration: float | None = None
    time: float | None = None
    report: Mapping[str, Any] | None = None
    raw: Mapping[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def parse(cls, body: Mapping[str, Any]) -> ExecutionEvent:
        """Raises: MalformedReply for a reply that is no event of an execution."""
        kind, execution = body.get("event"), body.get("execution")
        if kind not in EVENT_KINDS or not isinstance(execution, str):
            raise MalformedReply("execute", "event", f"is not an execution event: "
                                 f"{json.dumps(body)[:200]}")
        report = body.get("report")
        if kind == "finished" and not isinstance(report, Mapping):
            raise MalformedReply("execute", "report", "is missing")
        return cls(kind, execution, _float(body.get("duration")), _float(body.get("time")),
                   report, body)


def describe(ev: ExecutionEvent) -> str | None:
    """One line for a reaction event (changed, stopped, replanned), None for the others."""
    b = ev.raw
    if ev.event == "changed":
        ids = ", ".join(f"{k} {' '.join(b[k])}" for k in ("added", "removed", "attached",
                                                           "detached") if b.get(k))
        what = f"scene revision {b.get('revision')}" + (f" ({ids})" if ids else "")
        if b.get("certified"):
            return f"{what}: the rest of the motion is still certified; going on"
        ref = b.get("refused") or {}
        where = f" at {ref['time']:.3f} s ({'/'.join(ref.get('pair', ()))})" \
            if "time" in ref else ""
        return f"{what}: the rest is no longer certified{where}: {b.get('action')}"
    if ev.event == "stopped":
        ms = b.get("stop_ms")
        rest = b.get("rest_at")
        return (f"stopped for revision {b.get('revision')}: stop command "
                f"{'?' if ms is None else f'{ms:.0f}'} ms after the apply arrived, at rest "
                f"at {'?' if rest is None else f'{rest:.3f}'} s of the trajectory "
                f"({'before' if b.get('before') else 'NOT before'} the first uncertified "
                "piece)")
    if ev.event == "replanned":
        if b.get("ok"):
            return f"replanned from the stopped state: {float(b['duration']):.3f} s"
        err = b.get("error") or {}
        return f"replanning failed: {err.get('code')}: {err.get('message')}"
    return None


def _float(v: object) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def stream(session: zenoh.Session, prefix: str, body: Mapping[str, Any], *,
           decode: Decode, silence: float,
           on_event: Callable[[ExecutionEvent], None] | None = None,
           cancel: threading.Event | None = None) -> ExecutionEvent:
    """Send the execute request ``body`` and follow its stream to the ``finished`` event
    (:func:`follow`, holding the client's liveliness token while it runs).

    Raises:
        ServiceError: the coded error the service answered (BUSY, NOT_AT_START, a port
            that failed mid-motion, ...); ServiceUnavailable when the stream ends without
            a report or goes silent.
    """
    client_id, key = uuid.uuid4().hex, f"{prefix}/execute"
    token = session.liveliness().declare_token(f"{key}/client/{client_id}")
    try:
        end = follow(session, prefix, key, {**body, "client": client_id}, decode=decode,
                     silence=silence, on_event=on_event, cancel=cancel, executes=True)
    finally:
        token.undeclare()
    assert end.finished is not None  # follow raises for a stream without its report
    return end.finished


@dataclass(frozen=True)
class StreamEnd:
    """How a stream ended: ``planned``, the body of a task's ``planned`` reply (None for
    an execute stream); ``finished``, the execution's last event (None for a task only
    planned, or cancelled before it moved)."""

    planned: Mapping[str, Any] | None
    finished: ExecutionEvent | None


def follow(session: zenoh.Session, prefix: str, key: str, body: Mapping[str, Any], *,
           decode: Decode, silence: float, executes: bool,
           on_event: Callable[[ExecutionEvent], None] | None = None,
           on_planned: Callable[[Mapping[str, Any]], None] | None = None,
           cancel: threading.Event | None = None) -> StreamEnd:
    """Send ``body`` to ``key`` (``<prefix>/execute`` or ``<prefix>/task``) and follow
    its stream: a task's ``planned`` reply, then an execution's ``started``,
    ``progress``, ``finished``. The one follower of the client, the CLI and the ROS 2
    task server.

    Args:
        decode: turns a reply into its JSON object, raising the coded error of an error
            reply (:func:`arduinobot.client.codec.decode_reply`).
        silence: give up after this long [s] without a reply (planning included).
        executes: whether the stream moves the robot (it must then end with
            ``finished``); a task only planned ends after ``planned``.
        on_event, on_planned: called with each execution event, and with the planned
            body, on this thread.
        cancel: once set, the execution is cancelled as soon as its id is known (set
            while a task plans, the arm is stopped as it starts; it stops smoothly and
            the stream still ends with its report).

    Raises:
        ServiceError: the coded error the service answered; ServiceUnavailable when the
            stream ends without what it owes (a report, a plan) or goes silent.
    """
    replies: queue.Queue[zenoh.Reply | None] = queue.Queue()
    session.get(key, zenoh.handlers.Callback(replies.put, lambda: replies.put(None)),
                payload=json.dumps(body), encoding=JSON,
                consolidation=zenoh.ConsolidationMode.NONE, timeout=STREAM_LIMIT)
    execution: str | None = None
    planned: Mapping[str, Any] | None = None
    cancelled = False
    heard = time.monotonic()
    while True:
        if cancel is not None and cancel.is_set() and execution and not cancelled:
            cancel_execution(session, prefix, execution, decode=decode)
            cancelled = True
        try:
            rep = replies.get(timeout=0.1)
        except queue.Empty:
            if time.monotonic() - heard > silence:
                raise ServiceUnavailable(
                    f"'{key}': no word from the service for {silence:g} s "
                    f"(execution {execution or 'not started'})", reason="timeout",
                    details={"key": key, "timeout": silence,
                             "execution": execution}) from None
            continue
        heard = time.monotonic()
        if rep is None:
            if planned is not None and not executes:
                return StreamEnd(planned, None)
            if planned is None and execution is None:
                raise ServiceUnavailable(f"no service answered on '{key}' (is `arduinobot "
                                         "serve` running there?)", reason="no_route",
                                         details={"key": key})
            raise ServiceUnavailable(f"the service ended the stream on '{key}' without "
                                     f"{'a report' if executes else 'a plan'}",
                                     reason="no_route", details={"key": key})
        got = decode(rep, key, silence)
        if got.get("event") == "planned" and planned is None and execution is None:
            planned = got
            if on_planned is not None:
                on_planned(got)
            continue
        ev = ExecutionEvent.parse(got)
        execution = ev.execution
        if on_event is not None:
            on_event(ev)
        if ev.event == "finished":
            return StreamEnd(planned, ev)


def cancel_execution(session: zenoh.Session, prefix: str, execution: str | None, *,
                     decode: Decode,
                     timeout: float = 5.0) -> str | None:
    """Ask the service to stop ``execution`` (None: whatever runs) smoothly; the id it
    cancelled, or None if that execution is not running.

    Raises:
        ServiceError: the service's coded refusal; ServiceUnavailable: no reply.
    """
    key = f"{prefix}/execute/cancel"
    body = {} if execution is None else {"execution": execution}
    for rep in session.get(key, payload=json.dumps(body), encoding=JSON,
                           timeout=timeout):
        got = decode(rep, key, timeout).get("cancelled")
        return got if isinstance(got, str) else None
    raise ServiceUnavailable(f"no service answered on '{key}'", reason="no_route",
                             details={"key": key})
