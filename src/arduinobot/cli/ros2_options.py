"""The ROS 2 graph options `serve --ros2` and `execute --ros2` share (see docs/ros2.md)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Literal

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
