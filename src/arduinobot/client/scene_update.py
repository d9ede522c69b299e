"""A read-modify-write of the kept scene that gets through however busy the scene is.

:func:`update_scene` reads the scene, asks the caller for the change to make from it, and
applies that change with ``if_revision`` at the revision read. A writer that loses the
race is handed the next turn by the service (``details.turn``,
:mod:`arduinobot.service.scene.turns` on the service's side): the retry reads again and
applies with it, so two writers in a loop take turns instead of one starving.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from arduinobot.client.errors import SceneConflict
from arduinobot.client.replies import SceneApplied, SceneReply

__all__ = ["SceneWriter", "update_scene"]

_log = logging.getLogger(__name__)


class SceneWriter(Protocol):
    """What reads and changes the kept scene (a ``PlannerClient``)."""

    def scene(self) -> SceneReply: ...

    def apply(self, change: Mapping[str, Any] | None = None) -> SceneApplied: ...


def update_scene(client: SceneWriter,
                 make_change: Callable[[SceneReply], Mapping[str, Any] | None], *,
                 attempts: int = 50) -> SceneApplied | None:
    """Apply ``make_change(scene)`` (an apply request: ``add``, ``remove``, ...) at the
    revision it was made from, reading again after each lost race, with the turn the
    service hands the loser; None if ``make_change`` returns None (nothing to do).

    Raises:
        SceneConflict: still losing after ``attempts`` reads (the last refusal).
        ValueError: ``attempts`` < 1.
        ServiceError: what an apply raises otherwise (InvalidRequest naming the field).
    """
    if attempts < 1:
        raise ValueError(f"attempts must be >= 1, not {attempts}")
    turn = "ask"  # handed the next turn if this writer loses a race
    for attempt in range(attempts):
        scene = client.scene()
        change = make_change(scene)
        if change is None:
            return None
        body = {**change, "if_revision": scene.revision, "turn": turn}
        try:
            return client.apply(body)
        except SceneConflict as e:
            if attempt == attempts - 1:
                raise
            turn = e.details.get("turn") or "ask"
            wait = float(e.details.get("retry_after", 0.0))
            _log.debug("scene update: lost a race at revision %s (turn %s), retry in %.3f s",
                       e.details.get("current_revision"), turn, wait)
            if wait > 0 and not e.details.get("turn"):
                time.sleep(wait)
    raise AssertionError("unreachable")  # the loop returns or raises
