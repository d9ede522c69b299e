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


def sniff(data: bytes) -> ImageFormat | None:
    """The format ``data``'s first bytes announce, None for neither PNG nor JPEG."""
    for name, magic in _MAGIC.items():
        if data.startswith(magic):
            return "png" if name == "png" else "jpeg"
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
