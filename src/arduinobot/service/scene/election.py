"""Who leads the kept scene: the live instance with the smallest id that answers.

A liveliness token (``<p>/alive/<id>``) says a session holds it, not that an instance
behind it takes changes: a hung process, a VM paused within Zenoh's lease, or a token
declared by something that is no ``serve`` would make every apply wait and end ``BUSY``
if the smallest token led. So each candidate, smallest id first, is asked on its
``<p>/instance/<id>/scene/ready`` key (answered on Zenoh's callback thread, never behind
the applies); one that does not answer within :data:`ASK_WAIT`, or answers that it is not
ready (stopped and not yet caught up), is passed over for :data:`PASS_OVER` and the next
answering id leads. Every instance asks the same candidates in the same order, so they
reach the same choice; one that missed an answer hears ``not_leader`` with the leader's
id from the instance it chose, and asks again (:meth:`Election.reconsider`).

A process that was stopped (SIGSTOP, a VM pause) may have missed changes without its
tokens ever going: a watch thread ticks every :data:`TICK`; a gap over :data:`STALL`
means this process did not run, and it is not ready until it has caught up.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.service.scene.members import Instances

_log = logging.getLogger(__name__)

#: How long a candidate has to answer whether it is ready to lead [s].
ASK_WAIT = 0.5
#: How long a candidate that did not answer (or was not ready) is passed over [s].
PASS_OVER = 2.0
#: [s] between the watch's ticks.
TICK = 0.25
#: A gap between ticks this long [s] means the process was stopped (not just busy).
STALL = 3.0


class Election:
    """This instance's view of who leads (see the module).

    Args:
        ready: whether this instance may lead now (caught up since its last stall).
        on_stall: called (on the watch thread) with the gap [s] when this process is
            found to have been stopped.
    """

    def __init__(self, session: zenoh.Session, prefix: str, me: str, instances: Instances,
                 *, ready: Callable[[], bool], on_stall: Callable[[float], None]) -> None:
        self.session, self.prefix, self.me = session, prefix, me
        self.instances = instances
        self._ready, self._on_stall = ready, on_stall
        self._passed: dict[str, float] = {}  # candidate -> monotonic time to ask again
        self._lock = threading.Lock()
        self._last = time.monotonic()  # the watch's last tick
        self._led: str | None = None  # the last choice, to log a change once
        self._stop = threading.Event()
        self._watch = threading.Thread(target=self._run, name="scene-watch", daemon=True)

    def key(self, inst: str) -> str:
        return f"{self.prefix}/instance/{inst}/scene/ready"

    def start(self) -> None:
        self._last = time.monotonic()
        self._watch.start()

    def close(self) -> None:
        self._stop.set()
        if self._watch.is_alive():
            self._watch.join(timeout=2 * TICK + 1.0)

    # -- this instance -----------------------------------------------------------------
    def stalled(self) -> bool:
        """Whether the watch has not ticked for :data:`STALL` (this process was stopped
        and the watch has not run since: it reports it on its next tick); never before
        the watch starts (a start's catch-up may take seconds)."""
        return self._watch.is_alive() and time.monotonic() - self._last > STALL

    def ready(self) -> bool:
        """Whether this instance may lead now."""
        return not self.stalled() and self._ready()

    def answer(self, query: zenoh.Query) -> None:
        """The ``scene/ready`` queryable's handler: cheap, on Zenoh's thread."""
        query.reply(query.key_expr, orjson.dumps({"ready": self.ready()}),
                    encoding=wire.JSON)

    def _run(self) -> None:
        while not self._stop.wait(TICK):
            now = time.monotonic()
            gap, self._last = now - self._last, now
            if gap > STALL:
                _log.warning("scene: this process did not run for %.1f s (stopped or "
                             "paused): it may have missed changes", gap)
                self._on_stall(gap)

    # -- the others --------------------------------------------------------------------
    def leader(self) -> str:
        """The smallest live id that answers it is ready (this instance if ready, else
        when none does: its applies are then refused until it has caught up)."""
        now = time.monotonic()
        passed: list[str] = []
        chosen = self.me
        for cand in sorted(self.instances.live() | {self.me}):
            if cand == self.me:
                if self.ready():
                    chosen = cand
                    break
                passed.append(cand)
                continue
            with self._lock:
                skip = self._passed.get(cand, 0.0) > now
            if not skip and self._asks_ready(cand):
                chosen = cand
                break
            if not skip:
                with self._lock:
                    self._passed[cand] = now + PASS_OVER
            passed.append(cand)
        if chosen != self._led:
            _log.info("scene: instance %s leads%s", chosen, f" (passed over, not answering "
                      f"or not ready: {', '.join(passed)})" if passed else "")
            self._led = chosen
        return chosen

    def reconsider(self, inst: str) -> None:
        """Ask ``inst`` again next time (another instance says it leads)."""
        with self._lock:
            self._passed.pop(inst, None)

    def _asks_ready(self, inst: str) -> bool:
        replies: Any = self.session.get(self.key(inst), timeout=ASK_WAIT)
        for r in replies:
            if r.ok is not None:
                try:
                    return orjson.loads(r.ok.payload.to_bytes()).get("ready") is True
                except (orjson.JSONDecodeError, AttributeError):
                    _log.warning("scene: instance %s answered %s with %r: passed over",
                                 inst, self.key(inst), r.ok.payload.to_bytes()[:100])
                    return False
        return False
