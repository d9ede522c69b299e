"""Opening a serial port for a driver: exclusively locked, 8N1, non-blocking reads, and
each way it fails coded with the port and the reason (the Arduino's and the Feetech bus's
drivers alike)."""

from __future__ import annotations

import errno
import os

from arduinobot.execution.robots.base import PortBusy, PortError, PortNotFound


def open_serial(port: str, baud: int, *, device: str, write_timeout: float) -> object:
    """An exclusively locked pyserial port (a path or a pyserial URL), 8N1, reads that
    never block, writes that give up after ``write_timeout`` [s].

    Args:
        device: what should be plugged in there, for the message ("the arduinobot",
            "the bus adapter").

    Raises:
        PortNotFound, PortBusy, PortError: with the port and the reason.
    """
    import serial  # pyserial: imported with a serial driver only

    if "://" not in port and not os.path.exists(port):
        raise PortNotFound(f"serial port {port} does not exist (is {device} plugged in? "
                           "`ls /dev/ttyACM* /dev/ttyUSB*` lists the candidates)",
                           details={"port": port})
    try:
        return serial.serial_for_url(port, baudrate=baud, bytesize=serial.EIGHTBITS,
                                     parity=serial.PARITY_NONE,
                                     stopbits=serial.STOPBITS_ONE, timeout=0,
                                     write_timeout=write_timeout, exclusive=True)
    except serial.SerialException as e:
        code = getattr(e, "errno", None)
        if "exclusively lock" in str(e) or code in (errno.EBUSY, errno.EAGAIN):
            raise PortBusy(f"serial port {port} is busy: another program holds it (a "
                           "serial monitor, another `arduinobot execute`, a ros2_control "
                           f"node); close it and retry ({e})", details={"port": port}) from None
        if code == errno.ENOENT:
            raise PortNotFound(f"serial port {port} does not exist ({e})",
                               details={"port": port}) from None
        if code == errno.EACCES:
            raise PortError(f"no permission to open {port}: add yourself to the "
                            f"'dialout' group ({e})", details={"port": port}) from None
        raise PortError(f"cannot open serial port {port}: {e}",
                        details={"port": port}) from None
