"""Running a named task of the service (``<prefix>/task`` with ``execute``) for a caller
that only reports progress: the ROS 2 ``/task_server`` action of ``serve --ros2``."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

import zenoh

from arduinobot.client.codec import decode_reply
from arduinobot.client.errors import ServiceError
from arduinobot.client.stream import STREAM_LIMIT, ExecutionEvent, follow
from arduinobot.contract.outcomes import succeeded

_log = logging.getLogger(__name__)


def run_named_task(session: zenoh.Session, prefix: str, number: int, *,
                   on_progress: Callable[[float], None], cancel: threading.Event) -> bool:
    """Run task ``number`` of the service's tasks.yaml on its robot through
    ``<prefix>/task`` (``execute: true``), as ``arduinobot task --remote`` does;
    ``on_progress`` gets the fraction [0, 1] of the task's duration done at each event;
    ``cancel`` set stops it through ``<prefix>/execute/cancel`` (smoothly). Whether it
    completed (a refusal or a failure is logged and answers False)."""
    duration = 0.0

    def on_event(ev: ExecutionEvent) -> None:
        nonlocal duration
        if ev.event == "started":
            duration = ev.duration or 0.0
            on_progress(0.0)
        elif ev.event == "progress" and duration > 0 and ev.time is not None:
            on_progress(ev.time / duration)
        elif ev.event == "finished" and _completed(ev):
            on_progress(1.0)

    try:
        # no silence bound: the action waits for planning as long as the service plans
        end = follow(session, prefix, f"{prefix}/task",
                     {"number": number, "execute": True, "trajectories": False},
                     decode=decode_reply, silence=STREAM_LIMIT, executes=True,
                     on_event=on_event, cancel=cancel)
    except ServiceError as e:
        _log.warning("task %d: %s", number, e)
        return False
    return end.finished is not None and _completed(end.finished)


def _completed(ev: ExecutionEvent) -> bool:
    return succeeded((ev.report or {}).get("outcome"))
