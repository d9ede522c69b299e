"""src/arduinobot/service/process/zygote.py and the worker's side of src/arduinobot/service/messages.py: a forked worker marks
each job taken in memory its pool maps (TakenMark), and the mark outlives the worker."""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading

import orjson
import pytest

from arduinobot.service.messages import Done, JobMsg, Success, TakenMark
from arduinobot.service.process.worker import DescriptionSpec
from arduinobot.service.process.zygote import Zygote
from tests.helpers.procs import wait_for


def test_a_mark_is_shared_through_its_fd():
    mark, fd = TakenMark.create()
    try:
        other = TakenMark(fd)  # what the other process maps from the fd it is handed
    finally:
        os.close(fd)
    assert mark.seq == other.seq == 0
    other.mark(2**40 + 3)
    assert mark.seq == 2**40 + 3


@pytest.mark.slow
def test_a_forked_worker_marks_each_job_as_it_arrives_and_the_mark_outlives_it():
    exits: list[tuple[int, str]] = []
    lost = threading.Event()
    z = Zygote(multiprocessing.get_context("forkserver"), DescriptionSpec(cache_dir=""),
               on_exit=lambda pid, how: exits.append((pid, how)), on_lost=lost.set)
    try:
        w = z.fork()
        assert w.taken.seq == 0
        for seq in (1, 2):
            w.conn.send(JobMsg(f"j{seq}", "fk", b'{"joints": {"joint_1": 0.25}}', 1e12,
                               seq=seq))
            done = w.conn.recv()  # nothing before the outcome: the mark is not a message
            assert isinstance(done, Done) and isinstance(done.outcome, Success)
            assert orjson.loads(done.outcome.body)["joints"]["joint_1"] == 0.25
            assert w.taken.seq == seq
        os.kill(w.pid, signal.SIGKILL)
        wait_for(lambda: any(pid == w.pid for pid, _ in exits))
        assert w.taken.seq == 2  # what a slot reads once its worker has died
    finally:
        z.close()
