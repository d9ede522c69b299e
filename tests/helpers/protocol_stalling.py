"""A pyserial URL handler (``stalling://NAME``) modelling a USB serial device whose far
end can stop reading: what it does not read stays in the port's output queue, which
``out_waiting`` reports, as a CDC-ACM or FTDI driver does (a pty always says 0).

Register with ``serial.protocol_handler_packages.append("tests.helpers")``; the test
holds the :class:`Device` by name and sets ``reading``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import urlparse

from serial.serialutil import PortNotOpenError, SerialBase


@dataclass
class Device:
    """The far end: while ``reading``, every byte is taken at once."""

    reading: bool = True
    unsent: int = 0
    received: list[bytes] = field(default_factory=list)  # writes it took, in order
    written: list[bytes] = field(default_factory=list)  # every write the driver made

    @property
    def writes(self) -> int:
        return len(self.written)


DEVICES: dict[str, Device] = {}


class Serial(SerialBase):
    def open(self) -> None:
        if self._port is None:
            raise ValueError("port must be set")
        self.device = DEVICES.setdefault(urlparse(self._port).netloc, Device())
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def _reconfigure_port(self, force_update: bool = False) -> None:
        pass

    def from_url(self, url: str) -> str:
        return url

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        self.device.written.append(bytes(data))
        if self.device.reading:
            self.device.received.append(bytes(data))
        else:
            self.device.unsent += len(data)
        return len(data)

    @property
    def out_waiting(self) -> int:
        return self.device.unsent

    @property
    def in_waiting(self) -> int:
        return 0

    def read(self, size: int = 1) -> bytes:
        return b""

    def reset_input_buffer(self) -> None:
        pass

    def reset_output_buffer(self) -> None:
        self.device.unsent = 0
