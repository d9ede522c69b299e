"""Camera images as the wire carries them (PNG/JPEG bytes), decoded and checked before
anything is looked for in them. Needs OpenCV (the ``see`` extra)."""

from __future__ import annotations

from typing import Literal

import numpy as np

from arduinobot.perception.errors import ImageInvalid

ImageFormat = Literal["png", "jpeg"]
_MAGIC: dict[str, bytes] = {"png": b"\x89PNG\r\n\x1a\n", "jpeg": b"\xff\xd8\xff"}

#: brightness spread (max - min, of 255) under which an image shows nothing
MIN_CONTRAST = 8
#: the most pixels an image may have (a Pi camera 3's full 4608 x 2592 is 11.9 M): read
#: from its header before decoding, so a small file cannot expand into gigabytes
MAX_PIXELS = 4096 * 4096
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def sniff(data: bytes) -> ImageFormat | None:
    """The format ``data``'s first bytes announce, None for neither PNG nor JPEG."""
    for name, magic in _MAGIC.items():
        if data.startswith(magic):
            return "png" if name == "png" else "jpeg"
    return None


def header_size(data: bytes, image_format: ImageFormat) -> tuple[int, int] | None:
    """(width, height) [px] from a PNG's IHDR or a JPEG's SOF header; None if the header
    is not where the format puts it (the decoder then says what is wrong)."""
    if image_format == "png":
        if len(data) < 24 or data[12:16] != b"IHDR":
            return None
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    i = 2
    while i + 9 <= len(data):
        if data[i] != 0xFF:
            return None
        kind, length = data[i + 1], int.from_bytes(data[i + 2:i + 4], "big")
        if kind in _JPEG_SOF:
            return int.from_bytes(data[i + 7:i + 9], "big"), int.from_bytes(data[i + 5:i + 7],
                                                                               "big")
        i += 2 + length
    return None


def decode_gray(data: bytes, *, image_format: ImageFormat | None = None) -> np.ndarray:
    """The image as 8-bit grey, shape (height, width).

    Raises:
        ImageInvalid: not PNG/JPEG bytes (or not the ``image_format`` announced), not
            decodable, or all one colour (a capped lens, a dark room).
    """
    import cv2

    if not isinstance(data, (bytes, bytearray)) or not data:
        raise ImageInvalid("is empty")
    found = sniff(bytes(data[:8]))
    if found is None:
        raise ImageInvalid("is neither PNG nor JPEG (its first bytes are "
                           f"{bytes(data[:8])!r})")
    if image_format is not None and found != image_format:
        raise ImageInvalid(f"is announced as {image_format} but is {found}",
                           field="image.format")
    size = header_size(bytes(data), found)
    if size is not None and size[0] * size[1] > MAX_PIXELS:
        raise ImageInvalid(f"is {size[0]} x {size[1]} px, over the {MAX_PIXELS} px cap")
    gray = cv2.imdecode(np.frombuffer(bytes(data), dtype=np.uint8), cv2.IMREAD_GRAYSCALE)
    if gray is None or gray.size == 0:
        raise ImageInvalid(f"does not decode as {found} (truncated or corrupt)")
    spread = int(gray.max()) - int(gray.min())
    if spread < MIN_CONTRAST:
        raise ImageInvalid(f"is all one colour (brightness {int(gray.min())}..{int(gray.max())}"
                           " of 255): nothing can be seen in it")
    return np.asarray(gray)


def encode(rgb: np.ndarray, image_format: ImageFormat = "png", *, quality: int = 95) -> bytes:
    """An RGB image, shape (height, width, 3) uint8, as PNG or JPEG bytes."""
    import cv2

    bgr = cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_JPEG_QUALITY, quality] if image_format == "jpeg" else []
    ok, buf = cv2.imencode(".png" if image_format == "png" else ".jpg", bgr, params)
    if not ok:
        raise ImageInvalid(f"could not be encoded as {image_format}")
    return bytes(buf.tobytes())
