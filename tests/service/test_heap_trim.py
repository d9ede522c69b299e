"""The serving process gives freed heap back (issue 39, item 10: +19 MB/min in the soak,
glibc keeping what Python freed). Real glibc, a real fragmented heap: memory freed
between blocks still held stays resident until ``malloc_trim``."""

from __future__ import annotations

import os
import time

from arduinobot.service.process.heap_trim import HeapTrimmer, IdleTrim
from arduinobot.service.process.pool import rss_bytes

MIB = 1 << 20


def test_the_trimmer_gives_a_fragmented_heaps_free_pages_back(monkeypatch):
    monkeypatch.delenv("ARDUINOBOT_MALLOC_TRIM", raising=False)
    trimmer = HeapTrimmer(period=0.05)
    assert trimmer._trim is not None, "the service runs on glibc (Debian, Ubuntu)"
    blocks = [bytes(2048) + bytes([i % 256]) for i in range(60_000)]  # ~120 MiB of malloc
    kept = blocks[::60]  # one block in 60 stays: the heap cannot shrink from its top
    del blocks
    before = rss_bytes(os.getpid())
    trimmer.start()
    try:
        deadline = time.monotonic() + 60
        while trimmer.trims == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        trimmer.stop()
    after = rss_bytes(os.getpid())
    assert trimmer.trims >= 1
    assert before - after > 50 * MIB, (before / MIB, after / MIB)
    assert len(kept) == 1000


def test_turned_off_it_starts_no_thread(monkeypatch):
    monkeypatch.setenv("ARDUINOBOT_MALLOC_TRIM", "0")
    trimmer = HeapTrimmer(period=0.01)
    trimmer.start()
    assert trimmer._thread is None
    trimmer.stop()


def test_a_worker_trims_after_a_job_when_none_waits(monkeypatch):
    """A worker's job loop (service/process/worker.py) trims after a job when no other
    waits, at most every `gap` seconds; with another job waiting it does not."""
    monkeypatch.delenv("ARDUINOBOT_MALLOC_TRIM", raising=False)
    trim = IdleTrim(gap=3600.0)
    assert trim._trim is not None, "the service runs on glibc (Debian, Ubuntu)"
    blocks = [bytes(2048) + bytes([i % 256]) for i in range(60_000)]  # ~120 MiB of malloc
    kept = blocks[::60]
    del blocks
    trim.after_job(busy=True)  # another job waits: not now
    before = rss_bytes(os.getpid())
    assert trim.trims == 0
    trim.after_job(busy=False)
    after = rss_bytes(os.getpid())
    assert trim.trims == 1
    assert before - after > 50 * MIB, (before / MIB, after / MIB)
    again = [bytes(2048) + bytes([i % 256]) for i in range(60_000)]
    del again
    trim.after_job(busy=False)  # within the gap: not again
    assert trim.trims == 1 and len(kept) == 1000


def test_a_worker_does_not_trim_when_turned_off(monkeypatch):
    monkeypatch.setenv("ARDUINOBOT_MALLOC_TRIM", "0")
    trim = IdleTrim(gap=0.0)
    trim.after_job(busy=False)
    assert trim._trim is None and trim.trims == 0
