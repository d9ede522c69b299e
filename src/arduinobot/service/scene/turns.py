"""Fair ``if_revision`` races: the writer that loses one gets the next turn.

Two writers that each read the scene and apply with ``if_revision`` race; without help
the faster loop wins every time (a review saw one writer lose 400 races in a row). The
leader therefore hands the loser of a race that asked for turns (its apply's
``"turn": "ask"``) a *turn*: a token, good for :data:`TURN_TIME` seconds while the scene
stays at the revision the loser must read. A writer that does not ask is never handed
one, so writers that know nothing of turns never wait for a turn nobody will use.
While a turn is held, another conditional apply at that revision is refused
(``SCENE_CONFLICT``, ``details.reason`` ``turn_held``, ``retry_after`` [s]) and the
holder's apply with its ``turn`` goes through. An apply without ``if_revision`` is never
held up (it does not race), and a turn lapses when it is used, when it expires, or when
the scene moves on anyway. One turn at a time: a second loser gets the next one.

The leader applies one change at a time (one thread), so this holds no lock.
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["Turn", "Turns"]

#: How long a turn is held for the writer that lost a race [s]: reading the scene and
#: applying again takes milliseconds on a loaded machine; a writer that takes longer
#: loses the turn, not the scene.
TURN_TIME = 1.0


@dataclass(frozen=True)
class Turn:
    """A writer's turn: ``token`` to send as the apply's ``turn``, good while the scene
    is at ``revision`` until ``until`` (monotonic [s])."""

    token: str
    revision: int
    until: float


class Turns:
    """The leader's turn (see the module). ``clock``: monotonic seconds (for tests)."""

    def __init__(self, *, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._held: Turn | None = None

    def held(self, revision: int) -> Turn | None:
        """The turn held at ``revision``, None if none is (or it lapsed)."""
        t = self._held
        if t is not None and (t.revision != revision or self._clock() >= t.until):
            self._held = t = None
        return t

    def blocks(self, change: Mapping[str, Any], revision: int) -> float | None:
        """For a change to a scene at ``revision``: the seconds left of a turn it must
        wait for (a conditional apply at that revision without the turn's token), else
        None; the holder's change uses its turn up."""
        t = self.held(revision)
        if t is None or "if_revision" not in change:
            return None
        if change.get("turn") == t.token:
            self._held = None
            return None
        return max(t.until - self._clock(), 0.0)

    def lost(self, change: Mapping[str, Any], revision: int) -> Turn | None:
        """A conditional apply, ``change``, lost a race to a scene now at ``revision``: its
        turn, or None if it did not ask for turns (a ``turn`` of "ask" or a token) or
        another writer holds one."""
        if "turn" not in change or self.held(revision) is not None:
            return None
        self._held = Turn(secrets.token_hex(8), revision, self._clock() + TURN_TIME)
        return self._held
