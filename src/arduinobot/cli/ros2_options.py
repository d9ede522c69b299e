"""The ROS 2 graph options `serve --ros2` and `execute --ros2` share, and `serve`'s topics
in (--cloud-topic, --camera-topic; see docs/ros2.md)."""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass
from typing import Any, Literal

from arduinobot.cli.argtypes import UsageError

ATTACHMENT_LAYOUTS = ("current", "jazzy-0.2.3")


def add_ros2_args(g: argparse._ArgumentGroup) -> None:
    """The ROS 2 graph options ``serve --ros2`` and ``execute --ros2`` share."""
    g.add_argument("--ros-domain-id", type=int, default=None, metavar="N",
                   help="the ROS 2 domain, 0..232 (default: $ROS_DOMAIN_ID, else 0)")
    g.add_argument("--ros-namespace", default=None, metavar="NS",
                   help="the namespace of our node and of the names it uses (default /)")
    g.add_argument("--ros2-attachment", choices=ATTACHMENT_LAYOUTS, default=None,
                   help="rmw_zenoh's message attachment: current (Jazzy 0.2.4+, Kilted, "
                   "Rolling; default) or jazzy-0.2.3 (Jazzy's rmw_zenoh 0.2.0..0.2.3)")


@dataclass(frozen=True)
class Ros2Settings:
    """Where on the ROS 2 graph we appear: the domain, our namespace, the attachment."""

    domain_id: int
    namespace: str
    attachment: Literal["current", "jazzy-0.2.3"]


def ros2_settings(ns: argparse.Namespace, *, flag: str = "--ros2") -> Ros2Settings | None:
    """The ROS 2 options of ``ns`` (None without ``--ros2``).

    Raises:
        UsageError: a ROS 2 option without --ros2, or a domain id out of 0..232 (the
            flag's or $ROS_DOMAIN_ID's).
    """
    given = [f for f, v in (("--ros-domain-id", ns.ros_domain_id),
                            ("--ros-namespace", ns.ros_namespace),
                            ("--ros2-attachment", ns.ros2_attachment)) if v is not None]
    if not ns.ros2:
        if given:
            raise UsageError(f"{', '.join(given)} {'go' if len(given) > 1 else 'goes'} "
                             f"with {flag}")
        return None
    try:  # only now: the ros2 extra is optional
        from arduinobot.ros2 import InvalidName, InvalidOption
        from arduinobot.ros2.wire.names import domain_id_from_env, validate_namespace
    except ImportError as e:
        raise UsageError(f"{flag} needs the ros2 extra (pip install 'arduinobot[ros2]'): "
                         f"{e}") from e
    try:
        domain = domain_id_from_env() if ns.ros_domain_id is None else ns.ros_domain_id
    except InvalidOption as e:
        raise UsageError(e.message) from e
    if not 0 <= domain <= 232:
        raise UsageError(f"ROS 2 domain id {domain} is out of 0..232")
    try:
        namespace = validate_namespace(ns.ros_namespace or "/")
    except InvalidName as e:
        raise UsageError(f"--ros-namespace: {e.message}") from e
    return Ros2Settings(domain, namespace, ns.ros2_attachment or "current")


def add_ros2_input_args(g: argparse._ArgumentGroup) -> None:
    """``serve --ros2``'s topics in: a point cloud into the kept scene, a camera for
    perceive."""
    g.add_argument("--cloud-topic", metavar="TOPIC",
                   help="subscribe sensor_msgs/msg/PointCloud2 on TOPIC and keep its latest "
                   "cloud in the scene as one points object, in the link its frame_id names")
    g.add_argument("--cloud-rate", type=float, default=None, metavar="HZ",
                   help="the most clouds taken a second, each a new scene revision (default "
                   "1; at most 10)")
    g.add_argument("--cloud-id", default=None, metavar="ID",
                   help="the scene object the clouds become (default: cloud)")
    g.add_argument("--cloud-resolution", type=float, default=None, metavar="M",
                   help="the cloud's cells' edge [m] (default 0.01; 0.002 to 0.1)")
    g.add_argument("--camera-topic", metavar="TOPIC",
                   help="keep the latest sensor_msgs/msg/Image of TOPIC (and the CameraInfo "
                   "on its sibling camera_info) for perceive's image \"topic\" "
                   "(`scene see --topic`)")


_ID = re.compile(r"[A-Za-z0-9_.:-]{1,64}")


@dataclass(frozen=True)
class Ros2Inputs:
    """What ``serve`` subscribes: the extensions, and the camera perceive reads."""

    extensions: tuple[Any, ...]
    camera: Any


def ros2_inputs(ns: argparse.Namespace, lease: Any) -> Ros2Inputs:
    """The topics ``serve``'s options ask for, on the node ``lease`` gives (None without
    --ros2).

    Raises:
        UsageError: a topic option without --ros2, a cloud option without --cloud-topic,
            a bad topic name, id, rate or resolution.
    """
    cloud_opts = [f for f, v in (("--cloud-rate", ns.cloud_rate), ("--cloud-id", ns.cloud_id),
                                 ("--cloud-resolution", ns.cloud_resolution))
                  if v is not None]
    if lease is None:
        given = [f for f, v in (("--cloud-topic", ns.cloud_topic),
                                ("--camera-topic", ns.camera_topic)) if v] + cloud_opts
        if given:
            raise UsageError(f"{', '.join(given)} {'go' if len(given) > 1 else 'goes'} "
                             "with --ros2")
        return Ros2Inputs((), None)
    if ns.cloud_topic is None and cloud_opts:
        raise UsageError(f"{', '.join(cloud_opts)} {'go' if len(cloud_opts) > 1 else 'goes'}"
                         " with --cloud-topic")
    from arduinobot.ros2 import InvalidName, InvalidOption
    from arduinobot.ros2.wire.names import fully_qualified
    from arduinobot.service.ros2_inputs import TopicCamera, cloud_topic_extension
    extensions: list[Any] = []
    camera = None
    for flag, topic in (("--cloud-topic", ns.cloud_topic), ("--camera-topic", ns.camera_topic)):
        if topic is not None:
            try:
                fully_qualified(topic, "/")
            except InvalidName as e:
                raise UsageError(f"{flag}: {e.message}") from e
    if ns.cloud_topic is not None:
        from arduinobot.contract.errors import InvalidRequest
        from arduinobot.ros2.cloud_topic import CloudSettings
        from arduinobot.scene.cloud import check_resolution
        cloud_id = ns.cloud_id or "cloud"
        if not _ID.fullmatch(cloud_id):
            raise UsageError(f"--cloud-id {cloud_id!r}: 1 to 64 of A-Z a-z 0-9 _ . : -")
        try:
            resolution = check_resolution(0.01 if ns.cloud_resolution is None
                                          else ns.cloud_resolution, field="--cloud-resolution")
            settings = CloudSettings(ns.cloud_topic, cloud_id=cloud_id,
                                     rate=1.0 if ns.cloud_rate is None else ns.cloud_rate,
                                     resolution=resolution)
        except InvalidRequest as e:
            raise UsageError(e.message) from e
        except InvalidOption as e:
            raise UsageError(f"--cloud-rate: {e.message}") from e
        extensions.append(cloud_topic_extension(lease, settings))
    if ns.camera_topic is not None:
        camera = TopicCamera(lease, ns.camera_topic)
        extensions.append(camera.extension())
    return Ros2Inputs(tuple(extensions), camera)
