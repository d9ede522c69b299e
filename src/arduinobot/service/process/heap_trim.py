"""Give freed heap back to the system, now and then: the serving process's and each
worker's.

The serving process decodes and encodes every request's JSON, meshes and clouds; glibc
keeps what Python frees in its arenas, fragmented, so the resident set grew about
19 MB/min in a 5-minute mixed soak although the live data did not (``malloc_trim(0)``
gave back 48-61 MiB there: ``ARDUINOBOT_MEMTRACE_TRIM``, :mod:`.memtrace`). A daemon
thread calls ``malloc_trim(0)`` every :data:`TRIM_PERIOD` seconds (on glibc only; a few
milliseconds while it walks the arenas, on its own thread: a request's thread waits at
most for the allocator's lock). A worker trims in its job loop instead (no thread of its
own in a fork), after a job when no other waits, at most every :data:`WORKER_TRIM_GAP`
seconds (:class:`IdleTrim`): a plan's search trees, a task's or a cloud's arrays are
freed when the job ends.

The serving process also fixes glibc's mmap threshold at :data:`MMAP_THRESHOLD`: by
default glibc raises it to the size of each mmapped block freed (up to 32 MiB), so after
the first large apply every later mesh's base64 text (2.8 MB), its decoded JSON and its
copies come from the arenas, where the small objects around them keep the pages; mesh
churn held 429 MiB with the scene cleared (69 at start). Fixed, a block that large is
mapped and unmapped whole. ``ARDUINOBOT_MALLOC_TRIM=0`` turns all of it off (to measure the
difference: ``./dev bench soak``, ``./dev bench mesh_churn``).
"""

from __future__ import annotations

import ctypes
import logging
import math
import os
import threading
import time
from collections.abc import Callable

__all__ = ["HeapTrimmer", "IdleTrim"]

_log = logging.getLogger(__name__)

#: [s] between trims
TRIM_PERIOD = 10.0
#: [s] at least between a worker's trims (each walks its arenas: milliseconds)
WORKER_TRIM_GAP = 1.0
#: [bytes] the serving process's blocks from this size up are mapped on their own
MMAP_THRESHOLD = 256 * 1024
#: mallopt's parameter number of the threshold (glibc's malloc.h)
_M_MMAP_THRESHOLD = -3


def _malloc_trim() -> Callable[[int], int] | None:
    try:
        trim: Callable[[int], int] = ctypes.CDLL(None).malloc_trim
        return trim
    except (OSError, AttributeError):  # not glibc: nothing to give back this way
        return None


def _trim_if_on() -> Callable[[int], int] | None:
    """``malloc_trim``, unless ``ARDUINOBOT_MALLOC_TRIM=0`` or not glibc."""
    return _malloc_trim() if os.environ.get("ARDUINOBOT_MALLOC_TRIM", "1") != "0" else None


class IdleTrim:
    """A worker's trims: :meth:`after_job` when a job is answered (see the module).
    ``gap`` [s]."""

    def __init__(self, *, gap: float = WORKER_TRIM_GAP) -> None:
        self.gap = gap
        self.trims = 0  # how many trims gave something back
        self._trim = _trim_if_on()
        self._last = -math.inf

    def after_job(self, busy: bool) -> None:
        """Trim unless another job waits (``busy``), or the last trim was under ``gap``
        ago."""
        if self._trim is None or busy:
            return
        now = time.monotonic()
        if now - self._last >= self.gap:
            self._last = now
            if self._trim(0):
                self.trims += 1


class HeapTrimmer:
    """The thread (see the module); :meth:`start` and :meth:`stop`. ``period`` [s]."""

    def __init__(self, *, period: float = TRIM_PERIOD) -> None:
        self.period = period
        self.trims = 0  # how many trims gave something back
        self._trim = _trim_if_on()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Fix the mmap threshold and start trimming (nothing on a libc without
        ``malloc_trim``, or when turned off)."""
        if self._trim is not None:
            try:
                fixed = ctypes.CDLL(None).mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
            except (OSError, AttributeError):
                fixed = 0
            _log.debug("heap trim: mmap threshold %d bytes%s", MMAP_THRESHOLD,
                       "" if fixed else " not set (mallopt refused)")
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
