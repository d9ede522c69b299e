"""Give the serving process's freed heap back to the system, now and then.

The serving process decodes and encodes every request's JSON, meshes and clouds; glibc
keeps what Python frees in its arenas, fragmented, so the resident set grew about
19 MB/min in a 5-minute mixed soak although the live data did not (``malloc_trim(0)``
gave back 48-61 MiB there: ``ARDUINOBOT_MEMTRACE_TRIM``, :mod:`.memtrace`). A daemon
thread calls ``malloc_trim(0)`` every :data:`TRIM_PERIOD` seconds (on glibc only; a few
milliseconds while it walks the arenas, on its own thread: a request's thread waits at
most for the allocator's lock). ``ARDUINOBOT_MALLOC_TRIM=0`` turns it off (to measure
the difference: ``./dev bench soak``).
"""

from __future__ import annotations

import ctypes
import logging
import os
import threading
from collections.abc import Callable

__all__ = ["HeapTrimmer"]

_log = logging.getLogger(__name__)

#: [s] between trims
TRIM_PERIOD = 10.0


def _malloc_trim() -> Callable[[int], int] | None:
    try:
        trim: Callable[[int], int] = ctypes.CDLL(None).malloc_trim
        return trim
    except (OSError, AttributeError):  # not glibc: nothing to give back this way
        return None


class HeapTrimmer:
    """The thread (see the module); :meth:`start` and :meth:`stop`. ``period`` [s]."""

    def __init__(self, *, period: float = TRIM_PERIOD) -> None:
        self.period = period
        self.trims = 0  # how many trims gave something back
        self._trim = _malloc_trim() if os.environ.get("ARDUINOBOT_MALLOC_TRIM", "1") != "0" \
            else None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start trimming (nothing on a libc without ``malloc_trim``, or when turned off)."""
        if self._trim is None:
            _log.debug("heap trim: off (no glibc malloc_trim, or ARDUINOBOT_MALLOC_TRIM=0)")
            return
        self._thread = threading.Thread(target=self._run, name="heap-trim", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def _run(self) -> None:
        assert self._trim is not None
        while not self._stop.wait(self.period):
            if self._trim(0):
                self.trims += 1
