"""A camera's ``sensor_msgs/msg/Image`` topic, and its ``camera_info`` beside it, kept for
``<prefix>/perceive`` (``serve --ros2 --camera-topic TOPIC``).

A camera driver publishes an image and its ``sensor_msgs/msg/CameraInfo`` on the
sibling topic ``camera_info`` (``/camera/image_raw`` -> ``/camera/camera_info``, as
image_transport and camera_info_manager name them). Both subscriptions keep only the
latest message, undecoded: nothing is done per frame (a 2304 x 1296 RGB image at 30 Hz is
270 MB/s of pixels); :meth:`CameraTopic.latest` decodes the two on request. What the
pixels show is the service's business (``arduinobot.service.ros2_inputs``, through
perception, which nothing below the service imports).
"""

from __future__ import annotations

import logging
import threading
from typing import Any

from arduinobot.ros2.errors import MalformedCdr
from arduinobot.ros2.wire.node import Node
from arduinobot.ros2.wire.qos import SENSOR_DATA, QoS
from arduinobot.ros2.wire.topics import MessageInfo

log = logging.getLogger(__name__)

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"


def camera_info_topic(image_topic: str) -> str:
    """The CameraInfo topic beside fully qualified ``image_topic`` (its sibling
    ``camera_info``)."""
    parent = image_topic.rsplit("/", 1)[0]
    return f"{parent}/camera_info"


class CameraTopic:
    """Keeps the latest image of ``topic`` and the latest CameraInfo beside it."""

    def __init__(self, node: Node, topic: str, *, qos: QoS = SENSOR_DATA) -> None:
        self._lock = threading.Lock()
        self._image: Any = None
        self._info: Any = None
        self.images = 0
        self.image_sub = node.create_subscription(topic, IMAGE, self._on_image, qos=qos,
                                                  raw=True)
        self.topic = self.image_sub.endpoint.name
        self.info_topic = camera_info_topic(self.topic)
        self.info_sub = node.create_subscription(self.info_topic, CAMERA_INFO, self._on_info,
                                                 qos=qos, raw=True)
        self._types = node.types
        self.domain_id = node.info.domain_id
        log.info("ROS 2: %s (%s) and %s (%s) kept for <prefix>/perceive's image \"topic\": "
                 "the latest of each, decoded on request (keys %s, %s)", self.topic, IMAGE,
                 self.info_topic, CAMERA_INFO, self.image_sub.key, self.info_sub.key)

    def _on_image(self, payload: Any, info: MessageInfo) -> None:
        with self._lock:
            self._image = payload
            self.images += 1

    def _on_info(self, payload: Any, info: MessageInfo) -> None:
        with self._lock:
            self._info = payload

    def latest(self) -> tuple[Any, Any] | None:
        """The latest Image and CameraInfo messages, decoded (the CameraInfo None if
        none came, or it did not decode: logged); None before any image.

        Raises:
            MalformedCdr: the latest image is no CDR Image.
        """
        with self._lock:
            image, info = self._image, self._info
        if image is None:
            return None
        msg = self._types.deserialize(image.to_bytes(), IMAGE)
        calibration = None
        if info is not None:
            try:
                calibration = self._types.deserialize(info.to_bytes(), CAMERA_INFO)
            except MalformedCdr as e:  # the image is still good
                log.warning("ROS 2: %s: %s; the camera's intrinsics come from the request "
                            "or the model", self.info_topic, e)
        return msg, calibration

    def close(self) -> None:
        self.image_sub.close()
        self.info_sub.close()
