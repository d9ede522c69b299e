"""Artifacts worth keeping between runs, keyed by the content they were computed from.

The planner does no I/O: a caller that wants results kept (the service, the command
line) passes an object with this interface, e.g. :class:`arduinobot.service.process.disk_cache.DiskCache`.
Keys are content hashes, so a changed mesh, joint limit or algorithm is a new key and a
stale entry is never read.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Mapping
from typing import Protocol

import numpy as np


class ArtifactCache(Protocol):
    """Named arrays by (kind, key)."""

    def load(self, kind: str, key: str) -> Mapping[str, np.ndarray] | None:
        """The arrays stored under ``kind``/``key``, or None on a miss."""
        ...

    def store(self, kind: str, key: str, arrays: Mapping[str, np.ndarray]) -> None:
        """Keep ``arrays`` under ``kind``/``key`` (best effort: never raises for a full
        or read-only disk; it logs)."""
        ...


def content_key(parts: Iterable[bytes | str | np.ndarray]) -> str:
    """A hex SHA-256 over ``parts`` (arrays by dtype, shape and bytes)."""
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, np.ndarray):
            a = np.ascontiguousarray(p)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
        else:
            h.update(p.encode("utf-8") if isinstance(p, str) else p)
        h.update(b"\0")
    return h.hexdigest()
