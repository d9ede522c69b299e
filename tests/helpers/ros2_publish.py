"""An rmw_zenoh publisher written from the design document, with none of our ``ros2``
package, for tests: raw Zenoh puts on the key rmw_zenoh gives a topic
(``<domain>/<name>/<dds type>/<RIHS01 hash>``, the hash and the CDR from rosbags' own
Jazzy store) with the 33-byte attachment (sequence number, source timestamp, GID length
16, GID) as rmw_zenoh_cpp/src/detail/attachment_helpers.cpp @
534747dca92adf15e1b1b975123037ca278db5ba writes it; and the sensor messages tests send."""

from __future__ import annotations

import struct
import time
import uuid
from typing import Any

import numpy as np
import zenoh
from rosbags.typesys import Stores, get_typestore

ROSBAGS = get_typestore(Stores.ROS2_JAZZY)
T = ROSBAGS.types


class DesignPublisher:
    """Puts ``type_name`` messages on ``topic`` of ROS domain ``domain`` as an rmw_zenoh
    publisher does."""

    def __init__(self, session: zenoh.Session, domain: int, topic: str,
                 type_name: str) -> None:
        pkg, kind, name = type_name.split("/")
        self.type_name, self.z = type_name, session
        self.key = (f"{domain}/{topic.strip('/')}/{pkg}::{kind}::dds_::{name}_/"
                    f"{ROSBAGS.hash_rihs01(type_name)}")
        self.gid, self.seq = uuid.uuid4().bytes, 0

    def put(self, msg: Any) -> None:
        self.seq += 1
        att = struct.pack("<qq", self.seq, time.time_ns()) + bytes([16]) + self.gid
        self.z.put(self.key, bytes(ROSBAGS.serialize_cdr(msg, self.type_name)),
                   attachment=att)


def header(frame: str) -> Any:
    ns = time.time_ns()
    return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
        sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)


def cloud(points: np.ndarray, frame: str) -> Any:
    """An organised-as-one-row PointCloud2: x, y, z float32 and an rgb float between
    (16-byte points, as depth cameras pack them), not dense."""
    pf = T["sensor_msgs/msg/PointField"]
    rec = np.zeros(len(points), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                       ("rgb", "<f4")])
    rec["x"], rec["y"], rec["z"], rec["rgb"] = points[:, 0], points[:, 1], points[:, 2], 1.0
    return T["sensor_msgs/msg/PointCloud2"](
        header=header(frame), height=1, width=len(points),
        fields=[pf(name=n, offset=4 * i, datatype=7, count=1)
                for i, n in enumerate(("x", "y", "z", "rgb"))],
        is_bigendian=False, point_step=16, row_step=16 * len(points),
        data=np.frombuffer(rec.tobytes(), np.uint8), is_dense=False)
