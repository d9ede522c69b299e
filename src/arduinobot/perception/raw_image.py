"""Uncompressed camera images as a camera driver sends them (``sensor_msgs/msg/Image``:
width, height, row ``step`` [bytes], ``encoding``, endianness, the pixels), turned into
the 8-bit grey the marker detection reads. numpy only (no OpenCV), so a ROS topic's
latest image can be kept and converted on request.

Encodings (ROS's ``sensor_msgs/image_encodings.hpp`` names): ``mono8``/``8UC1``,
``mono16``/``16UC1`` (scaled to 8 bits by its own range), ``rgb8``, ``bgr8``/``8UC3``,
``rgba8``, ``bgra8``. Colour goes to grey with OpenCV's weights (0.299 R + 0.587 G +
0.114 B), so a PNG of the same pixels gives the same grey to within rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arduinobot.perception.errors import ImageInvalid
from arduinobot.perception.image import MAX_PIXELS, MIN_CONTRAST
from arduinobot.perception.intrinsics import Intrinsics

#: encoding -> (channels, bytes per channel, the channels' order)
ENCODINGS: dict[str, tuple[int, int, str]] = {
    "mono8": (1, 1, "l"), "8UC1": (1, 1, "l"), "mono16": (1, 2, "l"), "16UC1": (1, 2, "l"),
    "rgb8": (3, 1, "rgb"), "bgr8": (3, 1, "bgr"), "8UC3": (3, 1, "bgr"),
    "rgba8": (4, 1, "rgba"), "bgra8": (4, 1, "bgra"), "8UC4": (4, 1, "bgra"),
}
_WEIGHTS = {"r": 0.299, "g": 0.587, "b": 0.114}


def gray_of_raw(data: bytes, *, width: int, height: int, step: int, encoding: str,
                big_endian: bool = False, field: str = "image") -> np.ndarray:
    """The image's 8-bit grey, shape (height, width).

    Raises:
        ImageInvalid: an encoding not in :data:`ENCODINGS`, no pixels, more than
            :data:`~arduinobot.perception.image.MAX_PIXELS`, a ``step`` shorter than a
            row, less data than ``height`` rows, or all one colour.
    """
    if encoding not in ENCODINGS:
        raise ImageInvalid(f"encoding {encoding!r} is not one of {', '.join(ENCODINGS)} "
                           "(compressed and Bayer images are not read)",
                           field=f"{field}.encoding")
    if width <= 0 or height <= 0:
        raise ImageInvalid(f"is {width} x {height} px: no pixels", field=field)
    if width * height > MAX_PIXELS:
        raise ImageInvalid(f"is {width} x {height} px, over the {MAX_PIXELS} px cap",
                           field=field)
    channels, size, order = ENCODINGS[encoding]
    row = width * channels * size
    if step < row:
        raise ImageInvalid(f"step {step} is shorter than a row of {width} px of {encoding} "
                           f"({row} bytes)", field=f"{field}.step")
    if len(data) < step * (height - 1) + row:
        raise ImageInvalid(f"{len(data)} bytes of data, less than {height} rows of {step} "
                           "(truncated?)", field=f"{field}.data")
    dtype = np.dtype(np.uint8) if size == 1 else np.dtype(">u2" if big_endian else "<u2")
    rows = np.ndarray((height, width * channels), dtype=dtype, buffer=data,
                      strides=(step, size))
    pixels = rows.reshape(height, width, channels)
    if channels == 1:
        plane = pixels[:, :, 0].astype(np.float64)
        if size == 2:  # a depth or 16-bit mono image: its own range to 0..255
            lo, hi = float(plane.min()), float(plane.max())
            plane = (plane - lo) * (255.0 / (hi - lo)) if hi > lo else plane * 0.0
    else:
        plane = sum(_WEIGHTS[c] * pixels[:, :, i].astype(np.float64)
                    for i, c in enumerate(order) if c in _WEIGHTS)
    gray = np.clip(np.rint(plane), 0, 255).astype(np.uint8)
    spread = int(gray.max()) - int(gray.min())
    if spread < MIN_CONTRAST:
        raise ImageInvalid(f"is all one colour (brightness {int(gray.min())}..{int(gray.max())}"
                           " of 255): nothing can be seen in it", field=field)
    return gray


@dataclass(frozen=True, eq=False)
class CapturedImage:
    """A camera's latest image, as a topic delivered it.

    Attributes:
        gray: 8-bit grey, shape (height, width).
        intrinsics: the camera's calibration sent beside it (ROS CameraInfo), or None.
        frame_id: the frame the image says it was taken in (a link of the model, if the
            camera is in it).
        stamp: when it was taken [s since the UNIX epoch], as the camera stamped it.
        topic: where it came from; encoding: its pixels' encoding.
    """

    gray: np.ndarray
    intrinsics: Intrinsics | None
    frame_id: str
    stamp: float
    topic: str
    encoding: str

    def describe(self) -> dict[str, object]:
        """The wire's ``image`` of a perceive reply: where the image came from."""
        h, w = self.gray.shape
        return {"topic": self.topic, "frame_id": self.frame_id, "stamp": self.stamp,
                "width": int(w), "height": int(h), "encoding": self.encoding,
                "camera_info": self.intrinsics is not None}
