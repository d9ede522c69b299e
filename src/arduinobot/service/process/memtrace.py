"""Where a long-running server's memory goes: a debug probe for soak runs.

Off unless the environment sets ``ARDUINOBOT_MEMTRACE=<seconds>``: then the serving
process starts :mod:`tracemalloc` and, every that many seconds, logs (logger
``arduinobot.service.process.memtrace``, INFO) one line with its resident set, the bytes Python has
allocated (traced), glibc's heap in use and free (``mallinfo2``, every arena, so Rust's
allocations in Zenoh too), the resident set's anonymous, file and shared-memory parts,
and live-object counts the caller supplies; then the lines of
code whose traced memory grew most since the first probe. What it tells apart: growth in
Python objects (traced grows), in native allocations (malloc's in-use grows, traced
flat), or in memory freed but not returned to the system (malloc's free grows, in-use
flat). ``ARDUINOBOT_MEMTRACE_TRIM=1`` also calls ``malloc_trim(0)`` at each probe and logs
the resident set before and after it.
"""

from __future__ import annotations

import ctypes
import gc
import logging
import os
import threading
import tracemalloc
from collections import Counter
from collections.abc import Callable, Mapping

from arduinobot.service.process.slot import rss_bytes

_log = logging.getLogger(__name__)

ENV = "ARDUINOBOT_MEMTRACE"
ENV_TRIM = "ARDUINOBOT_MEMTRACE_TRIM"
_MIB = 2**20
#: how many growing lines of code each probe logs
_TOP = 8


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
        "uordblks", "fordblks", "keepcost")]


try:  # loaded once: a CDLL per probe shows up in the probe's own growth
    _LIBC: ctypes.CDLL | None = ctypes.CDLL(None)
except OSError:
    _LIBC = None


def malloc_heap() -> tuple[int, int] | None:
    """glibc's heap over every arena: (bytes in use, bytes free but kept), None when
    this is not glibc >= 2.33."""
    fn = getattr(_LIBC, "mallinfo2", None)
    if fn is None:
        return None
    fn.restype = _MallInfo2
    m = fn()
    return m.uordblks + m.hblkhd, m.fordblks


def rss_kinds() -> dict[str, int]:
    """This process's resident set by kind [bytes]: ``anon`` (heaps, stacks), ``file``
    (code, mapped files), ``shmem`` (shared memory, e.g. Zenoh's SHM pools)."""
    with open("/proc/self/status") as f:
        status = dict(line.split(":", 1) for line in f)  # e.g. "RssAnon:\t 1234 kB"
    return {k.lower(): int(status[f"Rss{k}"].split()[0]) * 1024
            for k in ("Anon", "File", "Shmem") if f"Rss{k}" in status}


def count_live(types: tuple[type, ...]) -> dict[str, int]:
    """How many instances of each of ``types`` the garbage collector tracks."""
    live = Counter(type(o).__name__ for o in gc.get_objects() if type(o) in types)
    return {t.__name__: live[t.__name__] for t in types}


class MemTrace:
    """The probe: a daemon thread logging every ``every`` seconds [s] (see the module).

    Args:
        every: seconds between probes [s].
        counts: called at each probe; its numbers (e.g. live jobs) are logged too.
        trim: call ``malloc_trim(0)`` at each probe and log the resident set after it.
    """

    def __init__(self, every: float, *, counts: Callable[[], Mapping[str, int]] | None = None,
                 trim: bool = False) -> None:
        if every <= 0:
            raise ValueError(f"every must be > 0 s, not {every}")
        self.every, self.counts, self.trim = every, counts, trim
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._base: tracemalloc.Snapshot | None = None

    @classmethod
    def from_env(cls, *, counts: Callable[[], Mapping[str, int]] | None = None
                 ) -> MemTrace | None:
        """The probe ``ARDUINOBOT_MEMTRACE`` asks for, started; None when unset.

        Raises:
            ValueError: the variable is not a positive number of seconds.
        """
        raw = os.environ.get(ENV, "")
        if not raw:
            return None
        try:
            every = float(raw)
        except ValueError:
            raise ValueError(f"{ENV}={raw!r}: give seconds between probes") from None
        probe = cls(every, counts=counts, trim=os.environ.get(ENV_TRIM, "") == "1")
        probe.start()
        return probe

    def start(self) -> None:
        tracemalloc.start(1)  # one frame per trace: deeper costs more memory
        self._thread = threading.Thread(target=self._run, name="memtrace", daemon=True)
        self._thread.start()
        _log.info("memtrace: probing every %g s (%s)", self.every, ENV)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        tracemalloc.stop()

    def _run(self) -> None:
        while not self._stop.wait(self.every):
            self.probe()

    def probe(self) -> None:
        """Log one probe (see the module)."""
        snap = tracemalloc.take_snapshot().filter_traces(
            (tracemalloc.Filter(False, tracemalloc.__file__),))
        traced = sum(s.size for s in snap.statistics("filename"))
        heap = malloc_heap()
        extra = dict(self.counts()) if self.counts is not None else {}
        rss, kinds = rss_bytes(os.getpid()), rss_kinds()
        trimmed = ""
        if self.trim:
            # glibc returns free heap memory to the system
            if _LIBC is not None and hasattr(_LIBC, "malloc_trim"):
                _LIBC.malloc_trim(0)
            trimmed = f" -> {rss_bytes(os.getpid()) / _MIB:.1f} MiB after malloc_trim"
        _log.info("memtrace: rss %.1f MiB (%s)%s, traced %.1f MiB, malloc in use %s, "
                  "free %s; %s", rss / _MIB,
                  ", ".join(f"{k} {v / _MIB:.1f}" for k, v in kinds.items()), trimmed,
                  traced / _MIB,
                  "?" if heap is None else f"{heap[0] / _MIB:.1f} MiB",
                  "?" if heap is None else f"{heap[1] / _MIB:.1f} MiB",
                  " ".join(f"{k}={v}" for k, v in extra.items()))
        if self._base is None:
            self._base = snap
            return
        for stat in snap.compare_to(self._base, "lineno")[:_TOP]:
            _log.info("memtrace:   %+.1f KiB (%+d blocks) %s", stat.size_diff / 1024,
                      stat.count_diff, stat.traceback[0])
