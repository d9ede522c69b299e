"""The Feetech STS/SCS bus protocol: instruction packets out, status packets back.

Half-duplex serial (1 Mbaud 8N1 by default): the host sends one instruction packet,
the addressed servo answers with one status packet; broadcast instructions (id 0xFE)
get no answer, except SYNC_READ, which each listed servo answers in turn::

    instruction:  FF FF  ID  LEN  INSTR  P0 .. Pn  CHK      LEN = n + 2
    status:       FF FF  ID  LEN  ERROR  P0 .. Pn  CHK
    CHK = ~(ID + LEN + INSTR|ERROR + P0 + .. + Pn) & 0xFF

Instructions: PING (1), READ (2: address, length), WRITE (3: address, data),
SYNC_READ (0x82: address, length, ids; STS/SMS only) and SYNC_WRITE (0x83: address,
length, then id and data per servo). Words are little-endian on STS/SMS servos and
big-endian on SCS ones. The ERROR byte's bits: voltage 1, angle sensor 2, overheat 4,
over-current 8, overload 32.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

from arduinobot.contract.codes import Code
from arduinobot.execution.robots.base import PortError, RobotError
from arduinobot.execution.robots.serial_port import open_serial

log = logging.getLogger(__name__)

Series = Literal["sts", "scs"]

BROADCAST = 0xFE
PING, READ, WRITE, SYNC_READ, SYNC_WRITE = 0x01, 0x02, 0x03, 0x82, 0x83
ERROR_BITS = {1: "input voltage", 2: "angle sensor", 4: "overheat", 8: "over-current",
              32: "overload"}


@dataclass(frozen=True)
class Register:
    """A control-table entry: ``address`` and ``size`` [bytes]."""

    address: int
    size: int


# the STS/SMS and SCS control tables agree on these (Feetech's manuals)
MODEL_NUMBER = Register(3, 2)
HOMING_OFFSET = Register(31, 2)  # STS/SMS only; sign-magnitude, sign bit 11
TORQUE_ENABLE = Register(40, 1)
GOAL_POSITION = Register(42, 2)
PRESENT_POSITION = Register(56, 2)
PRESENT_SPEED = Register(58, 2)  # sign-magnitude, sign bit 15 [steps/s]


class ServoNoResponse(RobotError):
    """A servo did not answer (unpowered, wrong id or baud rate, a loose cable)."""

    code: str = Code.SERVO_NO_RESPONSE


class ServoFault(RobotError):
    """A servo answered with an error bit set (overload, overheat, voltage, ...), or
    with a packet that does not parse."""

    code: str = Code.SERVO_FAULT


def checksum(body: Iterable[int]) -> int:
    """The packet checksum of ``body`` (id, length, instruction or error, parameters)."""
    return ~sum(body) & 0xFF


def instruction(servo: int, instr: int, params: Sequence[int] = ()) -> bytes:
    """One instruction packet."""
    body = [servo, len(params) + 2, instr, *params]
    return bytes([0xFF, 0xFF, *body, checksum(body)])


def sign_magnitude(value: int, sign_bit: int) -> int:
    """``value`` (raw register bits) as a signed integer: bit ``sign_bit`` is the sign."""
    mag = value & ((1 << sign_bit) - 1)
    return -mag if value & (1 << sign_bit) else mag


def to_sign_magnitude(value: int, sign_bit: int) -> int:
    """The register bits of the signed ``value``."""
    return (-value) | (1 << sign_bit) if value < 0 else value


def open_bus(port: str, baud: int) -> object:
    """The bus adapter's port (:func:`~arduinobot.execution.robots.serial_port.open_serial`;
    :class:`FeetechBus` sets its read timeout).

    Raises:
        PortNotFound, PortBusy, PortError: with the port and the reason.
    """
    return open_serial(port, baud, device="the bus adapter", write_timeout=1.0)


class FeetechBus:
    """Instruction/status exchanges on one open port.

    Args:
        serial_port: an open pyserial port (:func:`open_bus`).
        series: ``sts`` (STS/SMS: little-endian, SYNC_READ) or ``scs`` (big-endian,
            no SYNC_READ: one READ per servo).
        timeout: [s] to wait for a status packet.
        port: the port's name, for messages.
    """

    def __init__(self, serial_port: object, *, series: Series = "sts",
                 timeout: float = 0.05, port: str = "") -> None:
        self.serial = serial_port
        self.series = series
        self.timeout = timeout
        self.port = port
        # once: pyserial reconfigures the port (tcsetattr) at every timeout assignment
        serial_port.timeout = timeout  # type: ignore[attr-defined]

    # -- bytes ---------------------------------------------------------------------------
    def word(self, value: int) -> list[int]:
        """A 16-bit register value as bytes, in the series' order."""
        lo, hi = value & 0xFF, (value >> 8) & 0xFF
        return [lo, hi] if self.series == "sts" else [hi, lo]

    def unword(self, data: Sequence[int]) -> int:
        lo, hi = (data[0], data[1]) if self.series == "sts" else (data[1], data[0])
        return lo | (hi << 8)

    def _io_error(self, e: Exception, what: str) -> PortError:
        return PortError(f"{what} {self.port} failed: {e} (unplugged?)",
                         details={"port": self.port})

    def send(self, packet: bytes) -> None:
        """Write one instruction packet (stale input dropped first: half-duplex).

        Raises:
            PortError: the port failed (unplugged) or the write stalled.
        """
        try:
            self.serial.reset_input_buffer()  # type: ignore[attr-defined]
            self.serial.write(packet)  # type: ignore[attr-defined]
        except Exception as e:  # pyserial: SerialException, SerialTimeoutException, OSError
            raise self._io_error(e, "writing to") from e

    def _read(self, n: int, servo: int) -> bytes:
        try:
            data: bytes = self.serial.read(n)  # type: ignore[attr-defined]
        except Exception as e:  # pyserial: SerialException, OSError (EIO: unplugged)
            raise self._io_error(e, "reading from") from e
        if len(data) < n:
            raise ServoNoResponse(
                f"servo {servo} on {self.port} did not answer within {self.timeout:g} s "
                f"({len(data)} of {n} bytes; is it powered, on this bus, at this baud rate?)",
                details={"port": self.port, "servo": servo})
        return data

    def receive(self, servo: int, n_params: int) -> list[int]:
        """The parameters of ``servo``'s status packet (``n_params`` of them).

        Raises:
            ServoNoResponse: nothing (or too little) arrived in time.
            ServoFault: an error bit set, or a packet that does not parse.
        """
        # a header may come after stray bytes: skip to FF FF
        head = bytearray(self._read(4, servo))
        while head[:2] != b"\xff\xff":
            head = head[1:] + self._read(1, servo)
        sid, length = head[2], head[3]
        if length < 2:  # not even the error byte and the checksum: noise
            raise ServoFault(f"servo {servo} on {self.port}: a status packet of length "
                             f"{length} (at least 2)", details={"port": self.port,
                                                                "servo": servo})
        rest = self._read(length, servo)
        err, params, chk = rest[0], list(rest[1:-1]), rest[-1]
        parses = checksum([sid, length, err, *params]) == chk
        if parses and sid != servo:  # on a SYNC_READ, the next servo answered in its turn
            raise ServoNoResponse(f"servo {servo} on {self.port} did not answer (servo "
                                  f"{sid} answered in its turn)",
                                  details={"port": self.port, "servo": servo})
        if not parses or length != n_params + 2:
            raise ServoFault(f"servo {servo} on {self.port}: a status packet that does not "
                             f"parse (id {sid}, length {length}, checksum {chk:#04x})",
                             details={"port": self.port, "servo": servo, "packet":
                                      bytes(head + rest).hex()})
        if err:
            what = [name for bit, name in ERROR_BITS.items() if err & bit] or [f"{err:#04x}"]
            raise ServoFault(f"servo {servo} on {self.port} reports {', '.join(what)}",
                             details={"port": self.port, "servo": servo, "error": err,
                                      "errors": what})
        return params

    # -- instructions --------------------------------------------------------------------
    def ping(self, servo: int) -> None:
        """Raises :class:`ServoNoResponse` unless ``servo`` answers."""
        self.send(instruction(servo, PING))
        self.receive(servo, 0)

    def read(self, servo: int, reg: Register) -> list[int]:
        """The ``reg.size`` bytes of ``servo``'s register."""
        self.send(instruction(servo, READ, [reg.address, reg.size]))
        return self.receive(servo, reg.size)

    def read_word(self, servo: int, reg: Register) -> int:
        return self.unword(self.read(servo, reg))

    def write(self, servo: int, reg: Register, data: Sequence[int]) -> None:
        """Write ``data`` at ``reg`` and wait for the servo's acknowledgement."""
        self.send(instruction(servo, WRITE, [reg.address, *data]))
        self.receive(servo, 0)

    def sync_write(self, reg: Register, data: Mapping[int, Sequence[int]]) -> None:
        """One broadcast packet writing ``data[servo]`` at ``reg`` of every servo (no
        answer: a servo that misses it is found by the next read)."""
        params = [reg.address, reg.size]
        for servo, d in data.items():
            params += [servo, *d]
        self.send(instruction(BROADCAST, SYNC_WRITE, params))

    def sync_read(self, reg: Register, servos: Sequence[int]) -> dict[int, list[int]]:
        """``reg`` of every servo: one SYNC_READ (STS/SMS) or one READ each (SCS)."""
        if self.series == "scs":
            return {s: self.read(s, reg) for s in servos}
        self.send(instruction(BROADCAST, SYNC_READ, [reg.address, reg.size, *servos]))
        return {s: self.receive(s, reg.size) for s in servos}
