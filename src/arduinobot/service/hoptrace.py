"""Where a work request's time goes between Zenoh's callback and its reply: a debug probe
for the service hop (``bench/hop.py`` reads it).

Off unless the environment sets ``ARDUINOBOT_HOPTRACE=<file>``: then the serving process
appends one JSON line per answered work request to that file::

    {"request_id": "...", "kind": "plan", "stamps": {"callback": t, ...}}

Each stamp is :func:`time.monotonic` [s] (CLOCK_MONOTONIC: one clock for every process of
the host, so a client on the same host can put its own stamps beside them). In order:

- ``callback``: Zenoh called the queryable; ``queued``: the job goes to the pool;
- ``slot``: it is being sent to a worker (by the submitting thread when a worker waits
  idle, else by the slot thread that took it from the queue); ``sent``: its JobMsg is
  on the worker's socket;
- ``w_recv``, ``w_decoded``, ``w_handled``, ``w_encoded``: the worker received it,
  decoded and validated it, the handler returned, the reply is encoded;
- ``done``: the slot received the outcome; ``replied``: ``query.reply`` returned;
  ``final``: the query was finalised (the querier's get may end).

Off, it costs one boolean test per stage.
"""

from __future__ import annotations

import json
import logging
import os
import threading
import time

_log = logging.getLogger(__name__)

ENV = "ARDUINOBOT_HOPTRACE"
#: where the lines go (None: tracing off)
PATH: str | None = os.environ.get(ENV) or None
ON: bool = PATH is not None
#: the worker's stamps, in the order :class:`~arduinobot.service.messages.Done` carries them
WORKER_STAMPS = ("w_recv", "w_decoded", "w_handled", "w_encoded")

_lock = threading.Lock()

now = time.monotonic


def write(request_id: str, kind: str, stamps: dict[str, float]) -> None:
    """Append one request's stamps to :data:`PATH` (a no-op when tracing is off)."""
    if PATH is None:
        return
    line = json.dumps({"request_id": request_id, "kind": kind, "stamps": stamps})
    try:
        with _lock, open(PATH, "a", encoding="utf-8") as f:
            f.write(line + "\n")
    except OSError as e:  # a probe must not fail a request: logged, the reply is sent
        _log.warning("hop trace: cannot write %s: %s", PATH, e)
