"""Uncompressed images (a ROS sensor_msgs/msg/Image's pixels) to grey, against OpenCV's
own conversions, and refused naming the field when they cannot be read."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.perception.errors import ImageInvalid
from arduinobot.perception.raw_image import gray_of_raw

cv2 = pytest.importorskip("cv2")


@pytest.fixture
def rgb() -> np.ndarray:
    return np.random.default_rng(3).integers(0, 256, (7, 9, 3), dtype=np.uint8)


@pytest.mark.parametrize(("encoding", "pixels", "code"), [
    ("rgb8", lambda a: a, "COLOR_RGB2GRAY"),
    ("bgr8", lambda a: a[:, :, ::-1], "COLOR_BGR2GRAY"),
    ("rgba8", lambda a: np.dstack([a, np.full(a.shape[:2], 9, np.uint8)]), "COLOR_RGBA2GRAY"),
    ("bgra8", lambda a: np.dstack([a[:, :, ::-1], np.full(a.shape[:2], 9, np.uint8)]),
     "COLOR_BGRA2GRAY"),
])
def test_colour_to_grey_as_opencv_does(rgb, encoding, pixels, code):
    img = np.ascontiguousarray(pixels(rgb))
    h, w, c = img.shape
    row_pad = 5  # a driver's rows may end in padding
    data = b"".join(img[r].tobytes() + b"\x00" * row_pad for r in range(h))
    got = gray_of_raw(data, width=w, height=h, step=w * c + row_pad, encoding=encoding)
    want = cv2.cvtColor(img, getattr(cv2, code))
    assert got.shape == (h, w)
    assert np.abs(got.astype(int) - want.astype(int)).max() <= 1  # rounding


def test_mono8_as_is_and_mono16_either_endianness_to_its_range():
    mono = np.arange(48, dtype=np.uint8).reshape(6, 8) * 5
    np.testing.assert_array_equal(gray_of_raw(mono.tobytes(), width=8, height=6, step=8,
                                              encoding="mono8"), mono)
    deep = (np.arange(48, dtype=np.uint16).reshape(6, 8) * 1000 + 300)
    for big in (False, True):
        raw = deep.astype(">u2" if big else "<u2").tobytes()
        got = gray_of_raw(raw, width=8, height=6, step=16, encoding="16UC1", big_endian=big)
        want = np.rint((deep - 300) * (255.0 / (47 * 1000))).astype(np.uint8)
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(("kw", "field", "words"), [
    ({"encoding": "bayer_rggb8"}, "image.encoding", "not one of"),
    ({"step": 20}, "image.step", "shorter than a row"),
    ({"data": bytes(27 * 4)}, "image.data", "truncated"),
    ({"width": 0}, "image", "no pixels"),
    ({"data": bytes(27 * 5)}, "image", "all one colour"),
])
def test_unreadable_images_are_refused_naming_the_field(kw, field, words):
    args = {"data": bytes(range(135)), "width": 9, "height": 5, "step": 27,
            "encoding": "rgb8", **kw}
    with pytest.raises(ImageInvalid) as e:
        gray_of_raw(args.pop("data"), **args)
    assert e.value.details["field"] == field and words in str(e.value)
