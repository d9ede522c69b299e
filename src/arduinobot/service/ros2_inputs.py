"""ROS 2 topics into the service (``serve --ros2 --cloud-topic`` and ``--camera-topic``),
as extensions on the service's session (:mod:`arduinobot.service.extension`).

- a PointCloud2 topic (:mod:`arduinobot.ros2.cloud_topic`) becomes a ``points`` object
  of the kept scene, through ``<prefix>/scene/apply`` like any client's change (so it is
  filtered, kept on disk and replicated as any other), at the robot's state when it
  arrives;
- a camera's Image topic (:mod:`arduinobot.ros2.camera_topic`) is kept for
  ``<prefix>/perceive``: :class:`TopicCamera` is both the extension that subscribes and
  the image source the perceive service reads (``ServeOptions.camera``).

Both run on the service's one ROS 2 node, leased from ``serve``'s graph
(:class:`NodeLease`). The ``ros2`` package (its extra) is imported only when they start.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.perception.errors import ImageInvalid
from arduinobot.perception.intrinsics import Intrinsics
from arduinobot.service.extension import Extension, Host
from arduinobot.service.perceive.perceive_service import SceneApplyFailed

if TYPE_CHECKING:
    from arduinobot.perception.raw_image import CapturedImage
    from arduinobot.ros2.cloud_topic import CloudSettings

_log = logging.getLogger(__name__)

#: How long one cloud's apply may take [s]: a worker keeps it (~1 s for 30k points, a
#: few for 300k on a loaded machine) after the robot's state is read (at most 5 s).
CLOUD_APPLY_TIMEOUT = 60.0


class NodeLease(Protocol):
    """The service's one ROS 2 node: opened by the first that acquires it, closed when
    the last releases it."""

    def acquire(self, session: zenoh.Session) -> Any: ...

    def release(self) -> None: ...


class _Leased:
    """``inner`` whose close() also releases the node."""

    def __init__(self, inner: Any, lease: NodeLease) -> None:
        self._inner, self._lease = inner, lease

    def close(self) -> None:
        try:
            self._inner.close()
        finally:
            self._lease.release()


def scene_apply(session: zenoh.Session, prefix: str, change: Mapping[str, Any], *,
                timeout: float) -> dict[str, Any]:
    """``change`` through ``<prefix>/scene/apply``: the reply.

    Raises:
        SceneApplyFailed: the scene's refusal (its code and details), or no answer (BUSY).
    """
    replies = list(session.get(f"{prefix}/scene/apply", payload=wire.encode(dict(change)),
                               timeout=timeout))
    for r in replies:
        if r.ok is not None:
            body: dict[str, Any] = orjson.loads(r.ok.payload.to_bytes())
            return body
        err = orjson.loads(r.err.payload.to_bytes()).get("error", {})
        raise SceneApplyFailed(str(err.get("code", Code.INTERNAL)), str(err.get("message", "")),
                               err.get("details") or {})
    raise SceneApplyFailed(Code.BUSY, f"the kept scene did not answer in {timeout:g} s", {})


def cloud_topic_extension(lease: NodeLease, settings: CloudSettings) -> Extension:
    """Subscribes ``settings.topic`` (PointCloud2) and applies its clouds to the kept
    scene, at most ``settings.rate`` a second."""
    def make(host: Host) -> Any:
        from arduinobot.ros2.cloud_topic import CloudTopic

        def apply(obj: dict[str, Any]) -> Mapping[str, Any]:
            return scene_apply(host.session, host.prefix, {"add": [obj]},
                               timeout=CLOUD_APPLY_TIMEOUT)
        robot = host.description.robot
        node = lease.acquire(host.session)
        try:
            topic = CloudTopic(node, settings, links=tuple(robot.links), robot=robot.name,
                               apply=apply)
        except BaseException:
            lease.release()
            raise
        return _Leased(topic, lease)
    return make


#: CameraInfo distortion models whose D OpenCV takes as they are
_OPENCV_MODELS = ("plumb_bob", "rational_polynomial")


def intrinsics_of(info: Any) -> Intrinsics | None:
    """A CameraInfo message's pinhole (K, the image size, D when OpenCV's model), or None
    for an uncalibrated camera (K all zeros: the request's or the model's then)."""
    k = [float(x) for x in info.k]
    if len(k) != 9 or k[0] <= 0 or k[4] <= 0:
        return None
    d = [float(x) for x in info.d]
    if any(d) and str(info.distortion_model) not in _OPENCV_MODELS:
        _log.warning("ROS 2: CameraInfo's distortion model %r is not one OpenCV takes as it "
                     "is (%s): the image is measured as undistorted", info.distortion_model,
                     ", ".join(_OPENCV_MODELS))
        d = []
    return Intrinsics(fx=k[0], fy=k[4], cx=k[2], cy=k[5], width=int(info.width),
                      height=int(info.height), distortion=tuple(d) if any(d) else ())


class TopicCamera:
    """A camera topic for ``<prefix>/perceive``: :meth:`extension` subscribes it on the
    service's node; calling the object gives the latest image (``ServeOptions.camera``)."""

    def __init__(self, lease: NodeLease, topic: str) -> None:
        self.lease, self.topic = lease, topic
        self._camera: Any = None
        self._lock = threading.Lock()

    def extension(self) -> Extension:
        def make(host: Host) -> Any:
            from arduinobot.ros2.camera_topic import CameraTopic
            node = self.lease.acquire(host.session)
            try:
                camera = CameraTopic(node, self.topic)
            except BaseException:
                self.lease.release()
                raise
            with self._lock:
                self._camera = camera
            return _Leased(_Forget(self, camera), self.lease)
        return make

    def __call__(self) -> CapturedImage:
        """The latest image (see :meth:`arduinobot.ros2.camera_topic.CameraTopic.latest`).

        Raises:
            ImageInvalid: not subscribed (yet, or any more), no image yet, or unreadable.
        """
        from arduinobot.perception.raw_image import CapturedImage, gray_of_raw
        from arduinobot.ros2 import Ros2Error
        from arduinobot.ros2.camera_topic import IMAGE

        with self._lock:
            camera = self._camera
        if camera is None:
            raise ImageInvalid(f"the camera topic {self.topic} is not subscribed (the "
                               "service is starting or closing)")
        try:
            got = camera.latest()
        except Ros2Error as e:
            raise ImageInvalid(f"the latest message on {camera.topic} is no {IMAGE}: "
                               f"{e.message}") from e
        if got is None:
            raise ImageInvalid(f"no image has arrived on {camera.topic} yet (is the camera "
                               f"publishing {IMAGE} there, on ROS domain {camera.domain_id}, "
                               "behind the same Zenoh router?)")
        msg, info = got
        gray = gray_of_raw(bytes(msg.data), width=int(msg.width), height=int(msg.height),
                           step=int(msg.step), encoding=str(msg.encoding),
                           big_endian=bool(msg.is_bigendian))
        stamp = msg.header.stamp
        return CapturedImage(gray=gray, intrinsics=None if info is None else intrinsics_of(info),
                             frame_id=str(msg.header.frame_id),
                             stamp=int(stamp.sec) + int(stamp.nanosec) * 1e-9,
                             topic=camera.topic, encoding=str(msg.encoding))

    def forget(self) -> None:
        with self._lock:
            self._camera = None


class _Forget:
    """Closes the camera's subscriptions after the source stops handing it out."""

    def __init__(self, source: TopicCamera, camera: Any) -> None:
        self._source, self._camera = source, camera

    def close(self) -> None:
        self._source.forget()
        self._camera.close()
