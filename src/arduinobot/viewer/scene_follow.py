"""The viewer following the kept scene: each change the service applies is drawn.

The service publishes ``<prefix>/scene/changes`` once per applied revision
(:mod:`arduinobot.service.scene.sync`); a publication only wakes this follower, which then reads the
whole ``<prefix>/scene`` (a change names ids, not what they became) and draws it if its
revision is new. A publication can be missed (sent while the viewer was connecting, or
dropped with a link), so every ``poll`` seconds the service's ``health`` is asked for
its ``scene_revision`` (a few hundred bytes), and the whole scene read only if it moved.
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING

from arduinobot.client.errors import ServiceError
from arduinobot.contract.errors import InvalidRequest
from arduinobot.viewer.app import RobotViewer
from arduinobot.viewer.scene_view import ViewerScene

if TYPE_CHECKING:
    from arduinobot.client.client import PlannerClient

_log = logging.getLogger(__name__)


class SceneFollower:
    """Keeps ``viewer``'s kept scene at the service's newest revision.

    Args:
        viewer: the page.
        client: a session to the service (the caller's: it closes it).
        poll: seconds between reads without a publication [s].
    """

    def __init__(self, viewer: RobotViewer, client: PlannerClient, *,
                 poll: float = 10.0) -> None:
        self.viewer, self.client, self.poll = viewer, client, float(poll)
        self.key = f"{client.prefix}/scene/changes"
        #: revisions drawn, in order (the page's, for whoever waits on one)
        self.shown: list[int] = []
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._sub = client.session.declare_subscriber(self.key, lambda _s: self._wake.set())
        self._status = viewer.server.gui.add_markdown(f"**live** `{self.key}`: waiting")
        self._thread = threading.Thread(target=self._run, name="scene-follow", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        woken = True  # read the scene at the start
        while not self._stop.is_set():
            self._wake.clear()
            if woken or self._moved():
                self.refresh()
            woken = self._wake.wait(self.poll)

    def _moved(self) -> bool:
        """Whether the service's scene is at another revision than the one shown (or
        the service cannot say: then read the scene, which reports why)."""
        try:
            health = self.client.request("health", timeout=5.0)
        except ServiceError:
            return True
        return health.get("scene_revision") != self.viewer.scene.revision

    def refresh(self) -> bool:
        """Read ``<prefix>/scene`` and draw it if its revision is not the one shown;
        whether it drew. A scene it cannot read or show is said on the page (and the
        shown one kept)."""
        try:
            data = self.client.request("scene", timeout=10.0)
            if data.get("revision") == self.viewer.scene.revision:
                return False
            scene = ViewerScene.from_json(data, self.viewer.description,
                                          source=f"{self.client.prefix}/scene")
            self.viewer.set_scene(scene)
        except (ServiceError, InvalidRequest) as e:
            # the service away, or a scene this model cannot carry: the page says so
            # and the next change (or poll) tries again
            _log.warning("scene: %s", e)
            self._status.content = f"**live** `{self.key}`: {type(e).__name__}: {e}"
            return False
        self.shown.append(scene.revision)
        self._status.content = f"**live** `{self.key}`: {scene.summary()}"
        return True

    def close(self) -> None:
        self._stop.set()
        self._wake.set()
        self._thread.join(15.0)
        self._sub.undeclare()
