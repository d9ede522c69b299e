"""The attachment every rmw_zenoh put, query and reply carries.

Two layouts exist; both are zenoh-ext serialisations (little-endian integers, LEB128
lengths):

``"current"`` (Jazzy rmw_zenoh 0.2.4+, Kilted, Rolling 0.6.0+): 33 bytes ::

    int64 sequence_number | int64 source_timestamp [ns since the UNIX epoch]
    | 0x10 (the GID's length) | 16-byte GID

  rmw_zenoh_cpp/src/detail/attachment_helpers.cpp (src/arduinobot/ros2/rmw_zenoh @
  534747dca92adf15e1b1b975123037ca278db5ba, ``AttachmentData::serialize_to_zbytes``) and
  docs/design.md @ 99a6a2bd10b949052f4f12c5854825dc005e95a5 ("Publishers": "8 bytes for
  the sequence number ... 1 byte for the length of the publisher GID (currently always
  16)"). The change is "Change serialization format in attachment_helpers.cpp" (#601 on
  Rolling, 0.6.0; #605 on Jazzy, 0.2.4).

``"jazzy-0.2.3"`` (Jazzy rmw_zenoh 0.2.0 to 0.2.3): each value preceded by its name as a
  zenoh-ext string: ``"sequence_number"``, int64, ``"source_timestamp"``, int64,
  ``"source_gid"``, then the GID as a length-prefixed slice (``ze_serializer_serialize_str``
  / ``_int64`` / ``_buf`` in that release's attachment_helpers.cpp). A node on that
  release cannot read the current layout, nor the other way round: pick the layout with
  the ``attachment=`` option of :class:`arduinobot.ros2.wire.node.Node` (``sudo apt upgrade`` of
  ``ros-jazzy-rmw-zenoh-cpp`` is the better fix).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Literal

from arduinobot.ros2.errors import InvalidOption, MalformedAttachment

AttachmentLayout = Literal["current", "jazzy-0.2.3"]
LAYOUTS: tuple[str, ...] = ("current", "jazzy-0.2.3")

#: RMW_GID_STORAGE_SIZE since Jazzy (rmw/types.h).
GID_SIZE = 16
_KEYS = ("sequence_number", "source_timestamp", "source_gid")


def _leb128(n: int) -> bytes:
    out = bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


@dataclass(frozen=True)
class Attachment:
    """``sequence_number`` (per publisher or client, from 1), ``source_timestamp`` [ns
    since the UNIX epoch], ``gid`` (16 bytes: the sender's, or for a service reply the
    requesting client's)."""

    sequence_number: int
    source_timestamp: int
    gid: bytes

    def encode(self, layout: AttachmentLayout = "current") -> bytes:
        if len(self.gid) != GID_SIZE:
            raise MalformedAttachment(f"a GID has {GID_SIZE} bytes, not {len(self.gid)}",
                                      layout=layout, size=None)
        seq = struct.pack("<q", self.sequence_number)
        ts = struct.pack("<q", self.source_timestamp)
        gid = _leb128(GID_SIZE) + bytes(self.gid)
        if layout == "current":
            return seq + ts + gid
        if layout == "jazzy-0.2.3":
            def key(k: str) -> bytes:
                return _leb128(len(k)) + k.encode()
            return key(_KEYS[0]) + seq + key(_KEYS[1]) + ts + key(_KEYS[2]) + gid
        raise InvalidOption("attachment layout", layout, f"one of {LAYOUTS}")

    @classmethod
    def decode(cls, raw: bytes | None, layout: AttachmentLayout = "current") -> Attachment:
        """The attachment in ``raw``; :class:`MalformedAttachment` if it is missing, short,
        long, or not ``layout``."""
        if raw is None:
            raise MalformedAttachment("missing", layout=layout, size=None)
        reader = _Reader(bytes(raw), layout)
        if layout == "current":
            seq, ts = reader.int64(), reader.int64()
        elif layout == "jazzy-0.2.3":
            reader.key(_KEYS[0])
            seq = reader.int64()
            reader.key(_KEYS[1])
            ts = reader.int64()
            reader.key(_KEYS[2])
        else:
            raise InvalidOption("attachment layout", layout, f"one of {LAYOUTS}")
        gid = reader.slice()
        if len(gid) != GID_SIZE:
            reader.fail(f"the GID has {len(gid)} bytes, not {GID_SIZE}")
        reader.end()
        return cls(seq, ts, gid)


class _Reader:
    def __init__(self, raw: bytes, layout: str) -> None:
        self.raw, self.pos, self.layout = raw, 0, layout

    def fail(self, reason: str) -> None:
        raise MalformedAttachment(reason, layout=self.layout, size=len(self.raw))

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.raw):
            self.fail(f"truncated at byte {self.pos} (wanted {n} more)")
        out = self.raw[self.pos:self.pos + n]
        self.pos += n
        return out

    def int64(self) -> int:
        return struct.unpack("<q", self.take(8))[0]

    def length(self) -> int:
        n, shift = 0, 0
        for _ in range(10):
            byte = self.take(1)[0]
            n |= (byte & 0x7F) << shift
            if not byte & 0x80:
                return n
            shift += 7
        self.fail("a LEB128 length runs over 10 bytes")
        raise AssertionError  # unreachable: fail() raises

    def slice(self) -> bytes:
        return self.take(self.length())

    def key(self, want: str) -> None:
        got = self.slice()
        if got != want.encode():
            self.fail(f"expected the key {want!r}, found {got[:32]!r}")

    def end(self) -> None:
        if self.pos != len(self.raw):
            self.fail(f"{len(self.raw) - self.pos} bytes after the GID")
