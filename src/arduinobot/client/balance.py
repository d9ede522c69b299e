"""Which live instance a spreading client sends its next request to.

Instances are found by liveliness (``<prefix>/alive/<id>``), asked again every ``ttl``
seconds, and report their load on ``<prefix>/instance/<id>/health`` (``load``: busy
workers plus queued requests, per worker), asked in one wildcard query (~1 ms on a LAN)
whenever the last answer is older than ``load_ttl`` and the client is sending. That ask
runs in the background: a pick never waits for it (but the very first). The client adds
what it has itself in flight to each instance's reported load, so a burst from one client
spreads at once. Equal scores take turns, from a starting point of this session's own, so
that clients seeing the same loads do not all pick the same instance.
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
import time
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import orjson
import zenoh

_log = logging.getLogger(__name__)

#: how long a health reply may take before its instance counts as unknown load [s]
HEALTH_WAIT = 0.5


@dataclass(frozen=True)
class InstanceLoad:
    """What an instance last reported: ``load`` in jobs per worker (0 idle, 1 all busy,
    above 1 a queue; ``inf`` if it did not answer its health key in time)."""

    instance: str
    load: float
    workers: int


class LoadBalancer:
    """Live instances of one prefix on one session, and the least loaded of them.

    Args:
        ttl: how long the list of live instances is trusted [s].
        load_ttl: how old the reported loads may be before a pick asks again [s].
    """

    def __init__(self, session: zenoh.Session, prefix: str, *, ttl: float = 2.0,
                 load_ttl: float = 0.05) -> None:
        self.session, self.prefix = session, prefix
        self.ttl, self.load_ttl = float(ttl), float(load_ttl)
        self._lock = threading.Lock()
        self._live: tuple[str, ...] = ()
        self._loads: dict[str, InstanceLoad] = {}
        self._inflight: dict[str, int] = {}
        self._live_at = self._loads_at = -math.inf
        self._asking = False
        self._turn = itertools.count(int(str(session.zid())[:6] or "0", 16))

    def live(self, *, refresh: bool = False) -> tuple[str, ...]:
        """The ids of the live instances, asked again (with their loads) if older than
        ``ttl`` [s] or if ``refresh``."""
        with self._lock:
            stale = refresh or time.monotonic() - self._live_at >= self.ttl
        if stale:
            self._ask(live=True)
        with self._lock:
            return self._live

    def loads(self) -> dict[str, InstanceLoad]:
        """Each live instance's last reported load."""
        with self._lock:
            return {i: self._loads.get(i, InstanceLoad(i, math.inf, 1)) for i in self._live}

    def pick(self, exclude: Collection[str] = ()) -> str | None:
        """The least loaded live instance not in ``exclude`` (None if there is none)."""
        live = self.live()
        self._refresh_loads_in_background()
        with self._lock:
            candidates = [i for i in live if i not in exclude]
            if not candidates:
                return None
            scores = {i: self._score(i) for i in candidates}
            low = min(scores.values())
            best = [i for i in candidates if scores[i] == low]
            return best[next(self._turn) % len(best)]  # ties take turns

    def _score(self, instance: str) -> float:
        rep = self._loads.get(instance, InstanceLoad(instance, math.inf, 1))
        return rep.load + self._inflight.get(instance, 0) / max(1, rep.workers)

    @contextmanager
    def sending(self, instance: str) -> Iterator[None]:
        """Count a request to ``instance`` as in flight while the block runs."""
        with self._lock:
            self._inflight[instance] = self._inflight.get(instance, 0) + 1
        try:
            yield
        finally:
            with self._lock:
                self._inflight[instance] -= 1

    def forget(self, instance: str) -> None:
        """``instance`` did not answer: leave it out until the next ask finds it."""
        with self._lock:
            self._live = tuple(i for i in self._live if i != instance)
            self._live_at = -math.inf  # and ask again next time

    def _refresh_loads_in_background(self) -> None:
        with self._lock:
            if self._asking or time.monotonic() - self._loads_at < self.load_ttl:
                return
            self._asking = True
        threading.Thread(target=self._ask_in_background, daemon=True,
                         name="arduinobot-loads").start()

    def _ask_in_background(self) -> None:
        try:
            self._ask(live=False)
        except zenoh.ZError as e:  # e.g. the client closed its session meanwhile
            _log.debug("asking the instances' loads failed: %s", e)

    def _ask(self, *, live: bool) -> None:
        try:
            found = self._ask_live() if live else None
            loads = self._ask_loads()
        finally:
            with self._lock:
                self._asking = False
        now = time.monotonic()
        with self._lock:
            if found is not None:
                self._live, self._live_at = found, now
            self._loads, self._loads_at = loads, now

    def _ask_live(self) -> tuple[str, ...]:
        base = f"{self.prefix}/alive/"
        return tuple(sorted({str(r.ok.key_expr)[len(base):]
                             for r in self.session.liveliness().get(f"{base}*", timeout=2.0)
                             if r.ok is not None}))

    def _ask_loads(self) -> dict[str, InstanceLoad]:
        loads: dict[str, InstanceLoad] = {}
        for r in self.session.get(f"{self.prefix}/instance/*/health", timeout=HEALTH_WAIT):
            if r.ok is None:
                continue
            try:
                h = orjson.loads(r.ok.payload.to_bytes())
                w = h.get("workers", 1)  # the pool's list of workers, or a count
                rep = InstanceLoad(str(h["instance"]), float(h.get("load", 0.0)),
                                   len(w) if isinstance(w, list) else int(w))
            except (orjson.JSONDecodeError, KeyError, TypeError, ValueError) as e:
                _log.warning("%s: an unreadable health reply (%s); its load is unknown",
                             r.ok.key_expr, e)
                continue
            loads[rep.instance] = rep
        return loads
