"""sensor_msgs/msg/PointCloud2 to points: any fields layout holding x, y and z.

A depth camera driver packs each point as ``point_step`` bytes with named fields at
offsets (x, y, z and often rgb, intensity, padding), rows of ``row_step`` bytes (a row may
end in padding), big or little endian, and with NaN holes when ``is_dense`` is false.
The layout is read into one numpy record type with those offsets, so no byte is copied
but the three coordinates. Every size is checked against the data before it is viewed,
and the point count against :data:`arduinobot.scene.cloud.MAX_CLOUD_POINTS` before any
work: a message that lies about its layout is refused with
:class:`~arduinobot.contract.errors.InvalidRequest` naming the field (``cloud.fields``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene import cloud
from arduinobot.scene.cloud import DecodedPoints, finite_points

#: sensor_msgs/msg/PointField's datatype constants -> numpy scalar types
DATATYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def _field_of(fields: Any, name: str, where: str) -> tuple[int, str]:
    for f in fields:
        if f.name == name:
            if f.datatype not in DATATYPES:
                raise InvalidRequest(f"field '{name}' has datatype {f.datatype}, not one of "
                                     f"PointField's 1-8", field=f"{where}.fields")
            if f.count < 1:
                raise InvalidRequest(f"field '{name}' has count {f.count}",
                                     field=f"{where}.fields")
            return int(f.offset), DATATYPES[f.datatype]
    raise InvalidRequest(f"has no '{name}' field (fields: "
                         f"{', '.join(f.name for f in fields) or 'none'})",
                         field=f"{where}.fields")


def decode_pointcloud2(msg: Any, *, where: str = "cloud") -> DecodedPoints:
    """The finite points of a PointCloud2 message ``msg`` (rosbags' message object or
    anything with its attributes), in its ``header.frame_id``'s frame [m].

    Raises:
        InvalidRequest: no x, y or z field, a field beyond ``point_step``, rows longer
            than ``row_step``, less data than ``row_step * height``, more points than
            the cap (``details.limit``), or no finite point.
    """
    height, width = int(msg.height), int(msg.width)
    point_step, row_step = int(msg.point_step), int(msg.row_step)
    n = height * width
    if n > cloud.MAX_CLOUD_POINTS:
        raise InvalidRequest(f"{n} points, more than {cloud.MAX_CLOUD_POINTS}",
                             field=f"{where}.width", details={"limit": cloud.MAX_CLOUD_POINTS})
    if n == 0:
        raise InvalidRequest("has no point (width or height 0)", field=f"{where}.width")
    order = ">" if msg.is_bigendian else "<"
    names, offsets, formats = [], [], []
    for axis in ("x", "y", "z"):
        off, typ = _field_of(msg.fields, axis, where)
        size = np.dtype(typ).itemsize
        if off < 0 or off + size > point_step:
            raise InvalidRequest(f"field '{axis}' at offset {off} ({size} bytes) is beyond "
                                 f"point_step {point_step}", field=f"{where}.fields")
        names.append(axis)
        offsets.append(off)
        formats.append(order + typ)
    if width * point_step > row_step:
        raise InvalidRequest(f"a row of {width} points of {point_step} bytes is longer than "
                             f"row_step {row_step}", field=f"{where}.row_step")
    data = memoryview(bytes(msg.data)) if not isinstance(msg.data, (bytes, bytearray)) \
        else memoryview(msg.data)
    if len(data) < row_step * (height - 1) + width * point_step:
        raise InvalidRequest(f"{len(data)} bytes of data, less than {height} rows of "
                             f"{row_step} (truncated?)", field=f"{where}.data")
    record = np.dtype({"names": names, "offsets": offsets, "formats": formats,
                       "itemsize": point_step})
    grid = np.ndarray((height, width), dtype=record, buffer=data, strides=(row_step, point_step))
    xyz = np.column_stack([grid[a].reshape(-1).astype(np.float64) for a in names])
    return finite_points(xyz, field=f"{where}.data")
