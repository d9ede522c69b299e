"""A camera's ``sensor_msgs/msg/Image`` topic, and its ``camera_info`` beside it, kept for
``<prefix>/perceive`` (``serve --ros2 --camera-topic TOPIC``).

A camera driver publishes an image and its ``sensor_msgs/msg/CameraInfo`` on the
sibling topic ``camera_info`` (``/camera/image_raw`` -> ``/camera/camera_info``, as
image_transport and camera_info_manager name them). Both subscriptions keep only the
latest message, undecoded: nothing is done per frame (a 2304 x 1296 RGB image at 30 Hz is
270 MB/s of pixels); :meth:`CameraTopic.latest` decodes the two on request into a
:class:`~arduinobot.perception.raw_image.CapturedImage` (grey pixels, the calibration if
the camera sent one). A CameraInfo whose K is all zeros (an uncalibrated driver) gives no
intrinsics: the request's or the model's Gazebo sensor's are used then.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

from arduinobot.perception.errors import ImageInvalid
from arduinobot.perception.intrinsics import Intrinsics
from arduinobot.perception.raw_image import CapturedImage, gray_of_raw
from arduinobot.ros2.errors import MalformedCdr
from arduinobot.ros2.wire.node import Node
from arduinobot.ros2.wire.qos import SENSOR_DATA, QoS
from arduinobot.ros2.wire.topics import MessageInfo

log = logging.getLogger(__name__)

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
#: CameraInfo distortion models whose D OpenCV takes as they are
_OPENCV_MODELS = ("plumb_bob", "rational_polynomial")


def camera_info_topic(image_topic: str) -> str:
    """The CameraInfo topic beside fully qualified ``image_topic`` (its sibling
    ``camera_info``)."""
    parent = image_topic.rsplit("/", 1)[0]
    return f"{parent}/camera_info"


def intrinsics_of(info: Any) -> Intrinsics | None:
    """A CameraInfo message's pinhole (K, the image size, D when OpenCV's model), or None
    for an uncalibrated camera (K all zeros)."""
    k = [float(x) for x in info.k]
    if len(k) != 9 or k[0] <= 0 or k[4] <= 0:
        return None
    d = [float(x) for x in info.d] if str(info.distortion_model) in _OPENCV_MODELS else []
    return Intrinsics(fx=k[0], fy=k[4], cx=k[2], cy=k[5], width=int(info.width),
                      height=int(info.height), distortion=tuple(d) if any(d) else ())


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
        self._domain = node.info.domain_id
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

    def latest(self) -> CapturedImage:
        """The latest image, decoded, with the latest calibration.

        Raises:
            ImageInvalid: no image has arrived yet, or the latest is not a readable
                image (malformed CDR, an encoding not read, all one colour, ...).
        """
        with self._lock:
            image, info = self._image, self._info
        if image is None:
            raise ImageInvalid(f"no image has arrived on {self.topic} yet (is the camera "
                               f"publishing {IMAGE} there, on ROS domain {self._domain}, "
                               "behind the same Zenoh router?)")
        try:
            msg = self._types.deserialize(image.to_bytes(), IMAGE)
        except MalformedCdr as e:
            raise ImageInvalid(f"the latest message on {self.topic} is no {IMAGE}: "
                               f"{e.message}") from e
        gray = gray_of_raw(bytes(msg.data), width=int(msg.width), height=int(msg.height),
                           step=int(msg.step), encoding=str(msg.encoding),
                           big_endian=bool(msg.is_bigendian))
        intrinsics = None
        if info is not None:
            try:
                intrinsics = intrinsics_of(self._types.deserialize(info.to_bytes(),
                                                                   CAMERA_INFO))
            except MalformedCdr as e:  # the image is still good: the model's sensor then
                log.warning("ROS 2: %s: %s; the camera's intrinsics come from the request "
                            "or the model", self.info_topic, e)
        stamp = msg.header.stamp
        return CapturedImage(gray=gray, intrinsics=intrinsics,
                             frame_id=str(msg.header.frame_id),
                             stamp=int(stamp.sec) + int(stamp.nanosec) * 1e-9,
                             topic=self.topic, encoding=str(msg.encoding))

    def close(self) -> None:
        self.image_sub.close()
        self.info_sub.close()
