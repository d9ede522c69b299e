"""The viewer following a running ``arduinobot execute``: ``<prefix>/joint_states`` live.

The subscriber keeps only the newest message; a thread shows it at most ``rate`` times a
second (each pose also runs the collision check), so a 100 Hz stream never queues up.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from typing import Any

from arduinobot.viewer.app import RobotViewer

_log = logging.getLogger(__name__)


class JointStateFollower:
    """Shows every ``<prefix>/joint_states`` pose in ``viewer`` (sim or real arm).

    Args:
        viewer: the page.
        endpoint: the zenoh endpoint of the service (or a router) the states go through.
        prefix: the service's key prefix.
        rate: poses shown per second at most [Hz].
    """

    def __init__(self, viewer: RobotViewer, endpoint: str, *, prefix: str = "arduinobot",
                 rate: float = 30.0) -> None:
        from arduinobot.client.client import (
            PlannerClient,  # raises ServiceUnavailable if unreachable
        )
        self.viewer, self.period = viewer, 1.0 / rate
        self.key = f"{prefix}/joint_states"
        self._latest: dict[str, Any] | None = None
        self._cond = threading.Condition()
        self._stop = False
        self.shown = 0
        self.client = PlannerClient(endpoint, prefix=prefix)
        self._sub = self.client.session.declare_subscriber(self.key, self._on_sample)
        self._status = viewer.server.gui.add_markdown(f"**live** `{self.key}`: waiting")
        self._thread = threading.Thread(target=self._run, name="joint-states", daemon=True)
        self._thread.start()

    def _on_sample(self, sample: Any) -> None:
        try:
            msg = json.loads(sample.payload.to_bytes())
        except json.JSONDecodeError:
            _log.warning("%s: a payload that is not JSON", self.key)
            return
        with self._cond:
            self._latest = msg
            self._cond.notify()

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._latest is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                msg, self._latest = self._latest, None
            if msg is None:  # the wait ends on a message or on stop, which returned
                continue
            check = self.viewer.set_joints(dict(zip(msg.get("name", []),
                                                    msg.get("position", []))))
            self.shown += 1
            self._status.content = (
                f"**live** `{self.key}`: {msg.get('phase', '?')} "
                f"{100 * float(msg.get('progress') or 0):.0f}%"
                + ("" if check.valid else " — **collision**"))
            deadline = time.monotonic() + self.period  # at most `rate` poses a second
            with self._cond:
                while not self._stop and (left := deadline - time.monotonic()) > 0:
                    self._cond.wait(left)

    def close(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify()
        self._thread.join(2.0)
        self._sub.undeclare()
        self.client.close()
