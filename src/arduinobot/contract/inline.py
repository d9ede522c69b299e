"""Bytes sent inline in a JSON field (base64: a mesh file, a point cloud), decoded within
a size cap: the text's length is checked before anything is decoded, so an oversized
field costs no decoding."""

from __future__ import annotations

import base64
import binascii
import math

from arduinobot.contract.errors import InvalidRequest


def base64_cap(cap: int) -> int:
    """The longest base64 text [characters] of at most ``cap`` bytes."""
    return 4 * math.ceil(cap / 3)


def decode_inline(text: object, *, cap: int, noun: str, contents: str, field: str) -> bytes:
    """The bytes of the base64 ``text``, at most ``cap`` of them.

    Args:
        noun: what the bytes are, in refusals (``a mesh of more than ... bytes``).
        contents: what the text must hold (``the mesh file's bytes``).
        field: the field named in refusals (``add[3].mesh.data``).

    Raises:
        InvalidRequest: not a non-empty string, not valid base64, or over ``cap`` bytes
            (``details.limit``).
    """
    if not isinstance(text, str) or not text:
        raise InvalidRequest(f"must be {contents} in base64", field=field)
    if len(text) > base64_cap(cap):  # before decoding it
        raise InvalidRequest(f"a {noun} of more than {cap} bytes", field=field,
                             details={"limit": cap})
    try:
        raw = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise InvalidRequest("is not valid base64", field=field) from None
    if len(raw) > cap:
        raise InvalidRequest(f"a {noun} of {len(raw)} bytes, more than {cap}", field=field,
                             details={"limit": cap})
    return raw
