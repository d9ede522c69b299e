"""PointCloud2 decoding (arduinobot.ros2.pointcloud2) against rosbags' CDR of
sensor_msgs/msg/PointCloud2, the points packed byte by byte with ``struct``."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from arduinobot.contract.errors import InvalidRequest
from arduinobot.ros2.pointcloud2 import decode_pointcloud2
from arduinobot.ros2.wire.types import TypeStore
from arduinobot.scene import cloud

ROSBAGS = get_typestore(Stores.ROS2_JAZZY)
PC2 = "sensor_msgs/msg/PointCloud2"
PointField = ROSBAGS.types["sensor_msgs/msg/PointField"]
Header = ROSBAGS.types["std_msgs/msg/Header"]
Time = ROSBAGS.types["builtin_interfaces/msg/Time"]
_STRUCT = {7: "f", 8: "d", 5: "i", 2: "B", 4: "H"}


def _pack(points, layout, *, big: bool, point_step: int, width: int, row_pad: int) -> tuple:
    """Bytes of ``points`` (rows of width) in ``layout`` [(name, offset, datatype)], each
    value written by struct at its offset; padding bytes are 0xAB."""
    end = ">" if big else "<"
    rows = []
    for r in range(0, len(points), width):
        row = bytearray()
        for p in points[r:r + width]:
            rec = bytearray(b"\xab" * point_step)
            values = {"x": p[0], "y": p[1], "z": p[2], "rgb": 7, "intensity": 0.5}
            for name, off, dt in layout:
                struct.pack_into(end + _STRUCT[dt], rec, off, values[name])
            row += rec
        rows.append(bytes(row) + b"\xab" * row_pad)
    return b"".join(rows), width * point_step + row_pad


def _message(points, layout, *, big=False, point_step=16, width=None, row_pad=0,
             dense=True, frame="rgb_camera"):
    width = width or len(points)
    data, row_step = _pack(points, layout, big=big, point_step=point_step, width=width,
                           row_pad=row_pad)
    fields = [PointField(name=n, offset=o, datatype=d, count=1) for n, o, d in layout]
    msg = ROSBAGS.types[PC2](
        header=Header(stamp=Time(sec=1, nanosec=2), frame_id=frame),
        height=len(points) // width, width=width, fields=fields, is_bigendian=big,
        point_step=point_step, row_step=row_step,
        data=np.frombuffer(data, np.uint8), is_dense=dense)
    # over the wire as rosbags serialises it, back through our store
    raw = ROSBAGS.serialize_cdr(msg, PC2)
    return TypeStore().deserialize(raw, PC2)


@pytest.fixture
def pts():
    rng = np.random.default_rng(11)
    return rng.uniform(-2, 2, (24, 3)).astype(np.float32).astype(float)


def test_packed_xyz_little_endian(pts):
    m = _message(pts, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], point_step=12)
    out = decode_pointcloud2(m)
    np.testing.assert_array_equal(out.points, pts)
    assert out.dropped == 0 and m.header.frame_id == "rgb_camera"


def test_big_endian_fields_out_of_order_with_rgb_and_row_padding(pts):
    layout = [("z", 0, 8), ("rgb", 8, 5), ("x", 12, 8), ("intensity", 20, 7), ("y", 24, 8)]
    m = _message(pts, layout, big=True, point_step=36, width=6, row_pad=5)
    assert m.height == 4 and m.row_step == 6 * 36 + 5
    np.testing.assert_array_equal(decode_pointcloud2(m).points, pts)


def test_not_dense_drops_nan_points(pts):
    pts[[2, 9]] = math.nan
    m = _message(pts, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7)],
                 dense=False, width=8)
    out = decode_pointcloud2(m)
    assert out.dropped == 2 and len(out.points) == 22
    np.testing.assert_array_equal(out.points, pts[np.isfinite(pts).all(axis=1)])


@pytest.mark.parametrize("layout,point_step,field", [
    ([("x", 0, 7), ("y", 4, 7)], 12, "cloud.fields"),
    ([("x", 0, 7), ("y", 4, 7), ("z", 12, 7)], 12, "cloud.fields"),
    ([("x", 0, 7), ("y", 4, 7), ("z", 8, 9)], 12, "cloud.fields"),
])
def test_hostile_layouts_are_refused_naming_the_field(pts, layout, point_step, field):
    fields = [PointField(name=n, offset=o, datatype=d, count=1) for n, o, d in layout]
    msg = ROSBAGS.types[PC2](
        header=Header(stamp=Time(sec=0, nanosec=0), frame_id="world"), height=1,
        width=len(pts), fields=fields, is_bigendian=False, point_step=point_step,
        row_step=point_step * len(pts), data=np.zeros(point_step * len(pts), np.uint8),
        is_dense=True)
    with pytest.raises(InvalidRequest) as e:
        decode_pointcloud2(TypeStore().deserialize(ROSBAGS.serialize_cdr(msg, PC2), PC2))
    assert e.value.field == field


def test_truncated_data_and_too_many_points_are_refused(pts, monkeypatch):
    m = _message(pts, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], point_step=12)
    short = ROSBAGS.types[PC2](header=m.header, height=1, width=m.width, fields=m.fields,
                               is_bigendian=False, point_step=12, row_step=m.row_step,
                               data=np.asarray(m.data)[:-1], is_dense=True)
    with pytest.raises(InvalidRequest) as e:
        decode_pointcloud2(short)
    assert e.value.field == "cloud.data"
    monkeypatch.setattr(cloud, "MAX_CLOUD_POINTS", 23)
    with pytest.raises(InvalidRequest) as e:
        decode_pointcloud2(m)
    assert e.value.field == "cloud.width" and e.value.details["limit"] == 23
