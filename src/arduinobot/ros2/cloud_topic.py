"""A ``sensor_msgs/msg/PointCloud2`` topic into the kept scene: ``serve --ros2
--cloud-topic TOPIC``.

A depth camera publishes at 15-30 Hz; the kept scene takes a cloud as a new revision
(filtered against the robot, kept on disk, replicated), so the subscription keeps only
the latest message, undecoded (:class:`~arduinobot.ros2.wire.topics.Subscription`'s
``raw``), and one thread takes it at most ``rate`` times a second: decoded
(:func:`~arduinobot.ros2.pointcloud2.decode_pointcloud2`: any fields layout, either
endianness, NaN holes dropped), its ``header.frame_id`` checked against the model's links,
and handed to ``apply`` as a ``points`` object of the scene (``{"id", "shape": "points",
"points", "resolution", "frame": frame_id}``): the same id each time, so a later cloud
replaces the earlier one in one revision. A cloud slower to apply than ``1 / rate`` only
lowers the rate: the clouds that arrived meanwhile are skipped, never queued.

A message that cannot be used (malformed CDR, a frame that is no link, a layout without
x, y, z, a refusal of the scene) is logged with its code, counted in ``rejected``, and
dropped; the subscription keeps going. The first refusal of each kind is logged at
ERROR, later ones of the same kind at DEBUG (a camera at 30 Hz in the wrong frame would
flood the log otherwise).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import Any

from arduinobot.contract.errors import PlanningError
from arduinobot.ros2.errors import InvalidOption, Ros2Error, UnknownFrame
from arduinobot.ros2.wire.node import Node
from arduinobot.ros2.wire.qos import SENSOR_DATA, QoS
from arduinobot.ros2.wire.topics import MessageInfo

log = logging.getLogger(__name__)

POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
#: [Hz] the fastest a cloud may replace the last: each is a new scene revision
MAX_RATE = 10.0
#: sensor_msgs/msg/PointField's FLOAT64
_FLOAT64 = 8


@dataclass(frozen=True)
class CloudSettings:
    """What ``--cloud-topic`` and its options ask for.

    Attributes:
        topic: the PointCloud2 topic (relative names in the node's namespace).
        cloud_id: the scene object the clouds become (replaced by each).
        rate: the most clouds applied a second [Hz], in (0, :data:`MAX_RATE`].
        resolution: the cells' edge [m].
    """

    topic: str
    cloud_id: str = "cloud"
    rate: float = 1.0
    resolution: float = 0.01

    def __post_init__(self) -> None:
        if not 0.0 < self.rate <= MAX_RATE:
            raise InvalidOption("cloud rate", self.rate, f"in (0, {MAX_RATE:g}] Hz")


class CloudTopic:
    """Subscribes ``settings.topic`` on ``node`` and applies its clouds (see the module doc).

    Args:
        links: the model's link names (``"world"`` is taken too).
        robot: the model's name, for the messages.
        apply: puts one ``points`` object into the kept scene and returns the apply's
            reply (``revision``, ``clouds``); raises on a refusal.
    """

    def __init__(self, node: Node, settings: CloudSettings, *, links: Collection[str],
                 robot: str, apply: Callable[[dict[str, Any]], Mapping[str, Any]],
                 qos: QoS = SENSOR_DATA) -> None:
        self.settings, self._apply = settings, apply
        self._links, self._robot = frozenset(links) | {"world"}, robot
        self.applied = 0
        self.rejected = 0
        self.last_error: BaseException | None = None
        self.last_revision: int | None = None
        self._latest: tuple[Any, MessageInfo] | None = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._closed = threading.Event()
        self._said: set[str] = set()
        self.subscription = node.create_subscription(settings.topic, POINT_CLOUD2,
                                                     self._on_cloud, qos=qos, raw=True)
        self.topic = self.subscription.endpoint.name
        self._types = node.types
        self._thread = threading.Thread(target=self._run, name="ros2-cloud", daemon=True)
        self._thread.start()
        log.info("ROS 2: %s (%s) -> the kept scene's points object %r, at most %g Hz, "
                 "cells of %g m, in the frame each cloud names (key %s)", self.topic,
                 POINT_CLOUD2, settings.cloud_id, settings.rate, settings.resolution,
                 self.subscription.key)

    # -- Zenoh's thread: only keep the latest ------------------------------------------
    def _on_cloud(self, payload: Any, info: MessageInfo) -> None:
        with self._lock:
            self._latest = (payload, info)
        self._wake.set()

    # -- our thread: at most `rate` a second -------------------------------------------
    def _run(self) -> None:
        period = 1.0 / self.settings.rate
        next_at = 0.0
        while not self._closed.is_set():
            self._wake.wait()
            wait = next_at - time.monotonic()
            if wait > 0 and self._closed.wait(wait):
                break
            with self._lock:
                item, self._latest = self._latest, None
                self._wake.clear()
            if item is None or self._closed.is_set():
                continue
            next_at = time.monotonic() + period
            try:
                self._take(item[0])
            except Exception as e:  # a refusal or a bug: said, counted, the next cloud comes
                self._refused(e)

    def _take(self, payload: Any) -> None:
        from arduinobot.ros2.pointcloud2 import decode_pointcloud2
        from arduinobot.scene.cloud import encode_points

        msg = self._types.deserialize(payload.to_bytes(), POINT_CLOUD2)
        frame = str(msg.header.frame_id)
        if frame not in self._links:
            raise UnknownFrame(self.topic, frame, robot=self._robot,
                               links=sorted(self._links - {"world"}))
        points = decode_pointcloud2(msg, where="cloud")
        wide = any(f.name in ("x", "y", "z") and f.datatype == _FLOAT64 for f in msg.fields)
        obj = {"id": self.settings.cloud_id, "shape": "points",
               "points": encode_points(points.points, "xyz64" if wide else "xyz32"),
               "resolution": self.settings.resolution, "frame": frame}
        reply = self._apply(obj)
        self.applied += 1
        self.last_revision = int(reply.get("revision", -1))
        counts = dict((reply.get("clouds") or {}).get(self.settings.cloud_id, {}))
        say = log.info if self.applied == 1 else log.debug
        say("ROS 2: a cloud of %d points in %s -> scene revision %s: %s points kept, %d "
            "NaN dropped, %s on the robot, %s in objects%s", msg.width * msg.height, frame, reply.get("revision"), counts.get("kept", "?"), points.dropped,
            counts.get("filtered_robot", "?"), counts.get("filtered_objects", "?"),
            " (later clouds at DEBUG)" if self.applied == 1 else "")

    def _refused(self, e: BaseException) -> None:
        self.rejected += 1
        self.last_error = e
        if not isinstance(e, (Ros2Error, PlanningError)):  # a bug: with its traceback
            log.exception("ROS 2: a cloud on %s failed", self.topic)
            return
        code = str(getattr(e.code, "value", e.code))
        kind = f"{code}:{getattr(e, 'frame_id', '')}"
        first = kind not in self._said
        self._said.add(kind)
        (log.error if first else log.debug)(
            "ROS 2: dropped a cloud on %s: %s %s%s", self.topic, code, e.message,
            " (the same again at DEBUG)" if first else "")

    def close(self) -> None:
        self._closed.set()
        self._wake.set()
        self.subscription.close()
        self._thread.join(timeout=30)
