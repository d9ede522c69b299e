"""The real arduinobot over a serial port, speaking the course hardware interface's protocol.

115200 baud, 8N1. At each control tick, if the servo angles changed since the last
message, one ASCII message with no newline: ``b%03d,s%03d,e%03d,g%03d,`` where, from the
joint positions q1..q4 [rad] and integer truncation (Python's ``int``, toward zero)::

    b = int((q1 + pi/2) * 180 / pi)
    s = 180 - int((q2 + pi/2) * 180 / pi)
    e = int((q3 + pi/2) * 180 / pi)
    g = 180 - int((-q4 * 180) / (pi / 2))

each clamped to the servos' 0..180. The first command is always sent (the servos'
position at power-up is unknown). The arm reports nothing back: as in the course's
interface, the state is the last command (open loop), and before the first one the
initial positions (``initial_positions.yaml`` of the MoveIt package, else 0).

Safety: a command never moves a joint further than its velocity limit allows in one
tick (``velocity * period``), and never outside its URDF position limits.

A stalled arm: the port's driver buffers what the arm does not read (kilobytes: seconds
of messages), so a write fails only once that is full. After each write the driver asks
the port how many bytes are still unsent (``out_waiting``, where the port can tell) and
stops with ``PORT_ERROR`` (``stalled``) when, for :data:`STALL_TIME` on end, more is left
than the line could not yet have sent plus one message (the arm stopped reading: caught
in a few ticks, not the seconds a full buffer takes), or the newest command would reach
the arm more than :data:`MAX_LAG_TICKS` ticks late (a line too slow for the rate). A
backlog that drains within that time (a port flushing late on a busy machine, commands
written back to back) is not a stall. The arm reports nothing back: an execution that
ends is ``written``, not ``completed`` (:mod:`arduinobot.contract.outcomes`).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence

import numpy as np
from lxml import etree

from arduinobot.description import Description
from arduinobot.execution.robots.base import (
    JointState,
    MimicMap,
    PortError,
    PortNotFound,
    Robot,
    UnsupportedRobot,
    check_setpoint,
    initial_positions,
)
from arduinobot.execution.robots.serial_port import open_serial

log = logging.getLogger(__name__)

DEFAULT_BAUD = 115200
WRITE_TIMEOUT = 1.0  # [s] a write that takes longer means the arm stopped reading
MAX_LAG_TICKS = 2  # a command may wait at most this many ticks of line time to go out
STALL_TIME = 0.03  # [s] a backlog must last this long to be a stall (3 ticks at 100 Hz)


def servo_angles(q: Sequence[float] | np.ndarray) -> tuple[int, int, int, int]:
    """The servo angles [deg, 0..180] the protocol sends for joint positions ``q``
    (joint_1..joint_4) [rad], truncated as the course's interface does, then clamped."""
    q1, q2, q3, q4 = (float(v) for v in q)
    b = int((q1 + math.pi / 2) * 180 / math.pi)
    s = 180 - int((q2 + math.pi / 2) * 180 / math.pi)
    e = int((q3 + math.pi / 2) * 180 / math.pi)
    g = 180 - int((-q4 * 180) / (math.pi / 2))
    return tuple(min(180, max(0, v)) for v in (b, s, e, g))  # type: ignore[return-value]


def encode(angles: Sequence[int]) -> bytes:
    """One protocol message: ``b%03d,s%03d,e%03d,g%03d,`` in ASCII, no newline."""
    return b"b%03d,s%03d,e%03d,g%03d," % tuple(angles)


def hardware_params(urdf: str) -> dict[str, str]:
    """The ``<param>`` values of the ``<ros2_control><hardware>`` block of an expanded URDF
    that names a ``port`` (else of the first block; empty without one)."""
    root = etree.fromstring(urdf.encode("utf-8"))
    blocks = [{p.get("name"): (p.text or "").strip() for p in hw.iter("param") if p.get("name")}
              for hw in root.iter("hardware")
              if hw.getparent() is not None and hw.getparent().tag == "ros2_control"]
    return next((b for b in blocks if b.get("port")), blocks[0] if blocks else {})


def open_port(port: str, baud: int) -> object:
    """The arduinobot's port (:func:`~arduinobot.execution.robots.serial_port.open_serial`),
    writes giving up after :data:`WRITE_TIMEOUT`.

    Raises:
        PortNotFound, PortBusy, PortError: with the port and the reason.
    """
    return open_serial(port, baud, device="the arduinobot", write_timeout=WRITE_TIMEOUT)


class SerialArduinobot(Robot):
    """The arduinobot's Arduino on ``port``.

    Args:
        port: a device path (``/dev/ttyACM0``) or a pyserial URL.
        joint_names: the four actuated joints, in protocol order (b, s, e, g).
        velocity: per-joint velocity limits [rad/s], shape (4,).
        lower, upper: position limits [rad], shape (4,).
        rate: the control rate [Hz]: one tick moves a joint at most ``velocity / rate``.
        initial: positions [rad] before the first command (default 0).
        mimic: how the mimic joints follow (reported in the state).
        baud: [bit/s].
        boot_wait: seconds to wait after opening: an Arduino Uno resets when the port
            opens and ignores what arrives while its bootloader runs (~2 s).
    """

    realtime_only = True

    def __init__(self, port: str, *, joint_names: Sequence[str],
                 velocity: Sequence[float] | np.ndarray, lower: Sequence[float] | np.ndarray,
                 upper: Sequence[float] | np.ndarray, rate: float = 100.0,
                 initial: Sequence[float] | np.ndarray | None = None,
                 mimic: MimicMap | None = None,
                 baud: int = DEFAULT_BAUD, boot_wait: float = 0.0) -> None:
        self.joint_names = tuple(joint_names)
        if len(self.joint_names) != 4:
            raise UnsupportedRobot(f"the arduinobot protocol drives 4 joints (base, shoulder, "
                                   f"elbow, gripper); this robot has {len(self.joint_names)} "
                                   f"actuated: {', '.join(self.joint_names)}",
                                   details={"joints": list(self.joint_names)})
        if not (math.isfinite(rate) and rate > 0):
            raise UnsupportedRobot(f"rate {rate!r} must be a positive number [Hz]")
        self.mimic = mimic or MimicMap(self.joint_names, (), (), (), ())
        self.state_names = self.mimic.names
        self.period = 1.0 / rate
        self.velocity = check_setpoint(velocity, self.joint_names, "velocity limits")
        self.lower = check_setpoint(lower, self.joint_names, "lower limits")
        self.upper = check_setpoint(upper, self.joint_names, "upper limits")
        q0 = np.zeros(4) if initial is None else check_setpoint(initial, self.joint_names,
                                                                "initial positions")
        self._q = np.clip(q0, self.lower, self.upper)
        self._qd = np.zeros(4)
        self._last: tuple[int, int, int, int] | None = None
        self.limited = 0  # setpoints the step or position limits changed
        self.port = port
        self.baud = baud
        self._serial = open_port(port, baud)
        self._opened = time.monotonic()
        # (bytes unsent after the last write, when) for the stall check; None: the port
        # cannot tell its unsent bytes
        self._backlog: tuple[int, float] | None = self._read_backlog()
        self._stalling_since: float | None = None  # when the backlog stopped draining
        log.info("opened %s at %d baud (8N1)", port, baud)
        if boot_wait > 0:
            log.info("waiting %.1f s for the Arduino to boot", boot_wait)
            time.sleep(boot_wait)

    @classmethod
    def from_description(cls, description: Description, port: str | None = None, *,
                         baud: int | None = None, rate: float = 100.0,
                         boot_wait: float = 0.0) -> SerialArduinobot:
        """The driver for ``description``: limits from the URDF and joint_limits.yaml,
        initial positions from ``initial_positions.yaml``, and the port from the
        argument, else from the URDF's ros2_control ``<hardware>`` ``port`` param.

        Raises:
            PortNotFound: no port given and the URDF names none (or it does not exist).
        """
        from arduinobot.planner.kinematics.limits import JointLimits

        params = hardware_params(description.robot.urdf)
        port = port or params.get("port")
        if not port:
            why = ("its ros2_control <hardware> has no 'port' param (the simulation's? "
                   "try --arg is_sim=false)" if params or "<hardware" in description.robot.urdf
                   else "it has no ros2_control <hardware> block with a 'port' param")
            raise PortNotFound(f"no serial port: give --serial PORT, or load a URDF that "
                               f"names one ({why})")
        if baud is None:
            raw = params.get("baud_rate") or params.get("baudrate") or params.get("baud")
            baud = int(raw) if raw and raw.isdigit() else DEFAULT_BAUD
        mimic = MimicMap.from_description(description)
        lim = JointLimits.from_description(description, joint_names=mimic.actuated)
        return cls(port, joint_names=mimic.actuated, velocity=lim.velocity, lower=lim.lower,
                   upper=lim.upper, rate=rate,
                   initial=initial_positions(description, mimic.actuated), mimic=mimic,
                   baud=baud, boot_wait=boot_wait)

    def command(self, positions: Sequence[float] | np.ndarray,
                velocities: Sequence[float] | np.ndarray | None = None,
                accelerations: Sequence[float] | np.ndarray | None = None, *,
                jerks: Sequence[float] | np.ndarray | None = None) -> None:
        """Send the servo angles of ``positions`` [rad] if they changed (the protocol
        carries positions only: the rest is ignored)."""
        q = check_setpoint(positions, self.joint_names)
        step = self.velocity * self.period
        # one tick never moves a joint further than its velocity limit allows
        target = np.clip(np.clip(q, self._q - step, self._q + step), self.lower, self.upper)
        if np.any(np.abs(target - q) > 1e-9):
            self.limited += 1
            (log.warning if self.limited == 1 else log.debug)(
                "setpoint limited to one tick's motion / the position limits: asked %s, "
                "sending %s (further ones are logged at debug level)", np.round(q, 4),
                np.round(target, 4))
        angles = servo_angles(target)
        if angles != self._last:
            try:
                self._serial.write(encode(angles))  # type: ignore[attr-defined]
            except Exception as e:  # pyserial: SerialException / SerialTimeoutException
                # unplugged (EIO), or a write that stalled past write_timeout: the arm
                # holds the last angles it took, which stay the state
                stalled = type(e).__name__ == "SerialTimeoutException"
                raise PortError(
                    f"writing to {self.port} failed: "
                    + (f"the write stalled for {WRITE_TIMEOUT:g} s (the arm stopped "
                       "reading)" if stalled else f"{e} (unplugged?)"),
                    details={"port": self.port, "stalled": stalled,
                             "last_sent": None if self._last is None else list(self._last)}
                ) from e
            self._last = angles
            self._check_backlog(len(encode(angles)))
        self._qd = (target - self._q) / self.period
        self._q = target

    def _read_backlog(self) -> tuple[int, float] | None:
        """(unsent bytes, now), or None if the port cannot say (a pty says 0: fine)."""
        try:
            return int(self._serial.out_waiting), time.monotonic()  # type: ignore[attr-defined]
        except (AttributeError, NotImplementedError, OSError) as e:
            log.info("%s cannot tell how many bytes are unsent (%s): a stalled arm is "
                     "caught only when a write blocks for %g s", self.port, e, WRITE_TIMEOUT)
            return None

    def _check_backlog(self, message: int) -> None:
        """After writing a ``message``-byte command: refuse to go on if the arm stopped
        reading (more unsent than the line can have left since the last write) or the
        line lags more than :data:`MAX_LAG_TICKS` ticks.

        Raises:
            PortError: ``stalled``, with the unsent bytes.
        """
        if self._backlog is None:
            return
        before, then = self._backlog
        got = self._read_backlog()
        if got is None:
            self._backlog = None
            return
        unsent, now = got
        line = self.baud / 10.0  # [bytes/s]: 8N1 is 10 bits a byte
        # what the line cannot have sent yet of the earlier bytes, plus this message
        could_be_left = max(0.0, before - (now - then) * line) + message
        lag = unsent / line  # [s] until this command reaches the arm
        self._backlog = got
        stuck = unsent > could_be_left + message
        if not (stuck or lag > MAX_LAG_TICKS * self.period):
            self._stalling_since = None
            return
        if self._stalling_since is None:
            self._stalling_since = now
        if now - self._stalling_since >= STALL_TIME:
            why = ("the arm stopped reading" if stuck else
                   f"the line at {self.baud} baud is too slow for {1 / self.period:g} Hz")
            raise PortError(
                f"writing to {self.port} stalled: {unsent} bytes unsent, {1000 * lag:.0f} ms "
                f"of line time ({why})",
                details={"port": self.port, "stalled": True, "unsent": unsent,
                         "last_sent": None if self._last is None else list(self._last)})

    def advance(self, dt: float) -> None:
        """Hardware keeps its own time: the executor's clock paces the ticks."""

    def state(self) -> JointState:
        return JointState(self.state_names, tuple(map(float, self.mimic.expand(self._q))),
                          tuple(map(float, self.mimic.expand(self._qd, rate=True))), None,
                          time.monotonic() - self._opened)

    def close(self) -> None:
        s = getattr(self, "_serial", None)
        if s is not None and s.is_open:
            s.close()
