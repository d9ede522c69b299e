"""A simulated Feetech STS bus on a pseudo-terminal, written from the servos' manual
(Feetech's STS/SMS memory table and packet layout), not from the driver's code.

The driver opens :attr:`SimBus.path` (the pty's slave end); a thread on the master end
parses every instruction packet byte by byte and answers as servos would::

    FF FF  ID  LENGTH  INSTRUCTION  PARAM..  CHECKSUM
    LENGTH = number of params + 2; CHECKSUM = 255 - ((ID + LENGTH + INSTR + params) % 256)

A servo is a 256-byte memory: model number at 3 (777, the STS3215), Homing_Offset at 31
(sign bit 11), Torque_Enable at 40, Goal_Position at 42, Present_Position at 56 and
Present_Speed at 58 (little-endian words). With torque on, a servo is at its goal at
once (an ideal servo), unless it is ``stuck`` (a blocked joint: it stays put). A
``silent`` servo never answers.
"""

from __future__ import annotations

import os
import select
import threading
import tty
from dataclasses import dataclass, field


def manual_checksum(body: bytes | list[int]) -> int:
    return 255 - (sum(body) % 256)


@dataclass
class SimServo:
    """One servo's memory table and what happened to it."""

    id: int
    memory: bytearray = field(default_factory=lambda: bytearray(256))
    goals: list[int] = field(default_factory=list)  # every Goal_Position written [ticks]
    stuck: bool = False
    silent: bool = False
    error: int = 0  # the status packets' error byte (32: overload)

    def word(self, addr: int) -> int:
        return self.memory[addr] | (self.memory[addr + 1] << 8)

    def set_word(self, addr: int, value: int) -> None:
        self.memory[addr], self.memory[addr + 1] = value & 0xFF, (value >> 8) & 0xFF

    @property
    def present(self) -> int:
        return self.word(56)

    @property
    def torque(self) -> bool:
        return self.memory[40] == 1

    def write(self, addr: int, data: bytes) -> None:
        self.memory[addr:addr + len(data)] = data
        if addr <= 42 < addr + len(data):
            goal = self.word(42)
            self.goals.append(goal)
            if self.torque and not self.stuck:
                self.set_word(56, goal)


class SimBus:
    """Servos ``ids`` at rest at ``present`` ticks (by id), holding ``homing`` offsets."""

    def __init__(self, present: dict[int, int], *, homing: dict[int, int] | None = None
                 ) -> None:
        self.servos = {i: SimServo(i) for i in present}
        for i, s in self.servos.items():
            s.set_word(3, 777)
            off = (homing or {}).get(i, 0)
            s.set_word(31, (-off) | (1 << 11) if off < 0 else off)
            s.set_word(56, present[i])
        self.bad_checksums = 0
        self.packets: list[tuple[int, int, bytes]] = []  # (id, instruction, params)
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._buf = bytearray()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @classmethod
    def for_calibration(cls, calibration: dict[str, dict[str, int]]) -> SimBus:
        """The servos of a LeRobot calibration file (as parsed JSON), each holding its
        homing offset and resting in the middle of its range (0 rad on an arm joint)."""
        return cls({c["id"]: (c["range_min"] + c["range_max"]) // 2
                    for c in calibration.values()},
                   homing={c["id"]: c["homing_offset"] for c in calibration.values()})

    # -- the wire ------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            r, _, _ = select.select([self.master], [], [], 0.02)
            if not r:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:  # every slave end closed
                return
            self._buf += data
            self._parse()

    def _parse(self) -> None:
        while True:
            start = self._buf.find(b"\xff\xff")
            if start < 0 or len(self._buf) < start + 4:
                return
            length = self._buf[start + 3]
            end = start + 4 + length
            if len(self._buf) < end:
                return
            pkt = bytes(self._buf[start:end])
            del self._buf[:end]
            sid, instr, params, chk = pkt[2], pkt[4], pkt[5:-1], pkt[-1]
            if manual_checksum(pkt[2:-1]) != chk:
                self.bad_checksums += 1
                continue
            self.packets.append((sid, instr, params))
            self._handle(sid, instr, params)

    def _status(self, servo: SimServo, params: bytes = b"") -> None:
        if servo.silent:
            return
        body = bytes([servo.id, len(params) + 2, servo.error]) + params
        os.write(self.master, b"\xff\xff" + body + bytes([manual_checksum(body)]))

    def _handle(self, sid: int, instr: int, p: bytes) -> None:
        if instr == 0x83:  # SYNC_WRITE: addr, len, then (id, data) per servo; no answer
            addr, n = p[0], p[1]
            for k in range(2, len(p), n + 1):
                s = self.servos.get(p[k])
                if s is not None and not s.silent:
                    s.write(addr, p[k + 1:k + 1 + n])
            return
        if instr == 0x82:  # SYNC_READ: addr, len, ids; each answers in turn
            addr, n = p[0], p[1]
            for i in p[2:]:
                s = self.servos.get(i)
                if s is not None:
                    self._status(s, bytes(s.memory[addr:addr + n]))
            return
        s = self.servos.get(sid)
        if s is None:
            return
        if instr == 0x01:  # PING
            self._status(s)
        elif instr == 0x02:  # READ: addr, len
            self._status(s, bytes(s.memory[p[0]:p[0] + p[1]]))
        elif instr == 0x03:  # WRITE: addr, data
            if not s.silent:
                s.write(p[0], p[1:])
            self._status(s)

    # -- the test's side -----------------------------------------------------------------
    def unplug(self) -> None:
        """The adapter pulled: the far end goes away and the driver's port fails."""
        self._stop.set()
        self._thread.join()
        os.close(self.master)
        os.close(self.slave)

    def close(self) -> None:
        """Stop serving, after handling every byte the driver wrote: a SYNC_WRITE has no
        answer, so the driver's last one (the hold) may still be in the pty when the
        driver closes its port, as it would be on a wire that the servos still read."""
        if not self._stop.is_set():
            self._stop.set()
            self._thread.join()
            self._drain()
            os.close(self.master)
            os.close(self.slave)

    def _drain(self) -> None:
        while select.select([self.master], [], [], 0)[0]:
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            if not data:
                return
            self._buf += data
            self._parse()
