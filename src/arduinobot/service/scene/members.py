"""Which instances share the kept scene, as liveliness tokens tell it: the live ones
(``<p>/alive/<id>``, the candidates to lead: :mod:`.election`) and the members that hold the scene
(``<p>/scene/member/<id>``, the leader sends each change to each of them)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import zenoh


class Instances:
    """The ids of the live instances and the scene's members under ``prefix``, kept by
    liveliness subscribers (:meth:`subscribe`) that live as long as their entities."""

    def __init__(self, session: zenoh.Session, prefix: str, me: str, *,
                 on_return: Callable[[str], None] | None = None) -> None:
        """``on_return(id)`` is called (on Zenoh's callback thread: keep it short) when
        another instance's member token appears again after it went: that instance, or
        this one, was away (a pause or a partition past Zenoh's lease, a restart)."""
        self.session, self.prefix, self.me = session, prefix, me
        self._on_return = on_return
        self._gone: set[str] = set()  # members whose token went
        # kept by subscribers: a liveliness get per apply sometimes missed a token under
        # load, and an instance that misses the leader's leads too (two leaders lose
        # changes; measured with bench/scene.py)
        self._alive: set[str] = set()
        self._members: set[str] = set()
        self._lock = threading.Lock()

    def subscribe(self) -> list[Any]:
        """Declare the two subscribers (each sees the tokens already there); the entities
        to undeclare when done."""
        liveliness = self.session.liveliness()
        return [liveliness.declare_subscriber(f"{self.prefix}/alive/*",
                                              self._on_token(self._alive), history=True),
                liveliness.declare_subscriber(f"{self.prefix}/scene/member/*",
                                              self._on_token(self._members, self._gone),
                                              history=True)]

    def _on_token(self, ids: set[str], gone: set[str] | None = None
                  ) -> Callable[[zenoh.Sample], None]:
        """Keeps ``ids`` as the ids of the liveliness tokens a subscriber sees (and
        ``gone``: those it saw go, told to ``on_return`` when they come back)."""
        def on_sample(sample: zenoh.Sample) -> None:
            inst = str(sample.key_expr).rsplit("/", 1)[-1]
            back = False
            with self._lock:
                if sample.kind == zenoh.SampleKind.PUT:
                    ids.add(inst)
                    if gone is not None and inst in gone:
                        gone.discard(inst)
                        back = inst != self.me
                else:
                    ids.discard(inst)
                    if gone is not None:
                        gone.add(inst)
            if back and self._on_return is not None:
                self._on_return(inst)
        return on_sample

    def members(self) -> set[str]:
        """The other instances holding the scene."""
        with self._lock:
            return self._members - {self.me}

    def live(self) -> set[str]:
        """The ids of the instances with a liveliness token (the subscriber's view, and
        a get's while it may not have heard of them all yet)."""
        with self._lock:
            ids = set(self._alive)
        if not ids - {self.me}:  # just started, or alone: ask as well
            for reply in self.session.liveliness().get(f"{self.prefix}/alive/*",
                                                       timeout=2.0):
                if reply.ok is not None:
                    ids.add(str(reply.ok.key_expr).rsplit("/", 1)[-1])
        return ids
