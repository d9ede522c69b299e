"""An arm of Feetech STS/SCS bus servos (LeRobot's SO-100/SO-101: STS3215s at 1 Mbaud).

``arduinobot execute traj.json --driver feetech --port /dev/ttyACM0 --driver-option
calibration=~/.cache/huggingface/lerobot/calibration/robots/so101_follower/arm.json``

Each joint is a servo (its id from the LeRobot calibration file, the motor named like
the joint unless ``motor.JOINT=NAME`` says otherwise; see
:mod:`~arduinobot.execution.robots.feetech.calibration` for angles <-> ticks). Per tick:
one SYNC_WRITE of every goal position, then one SYNC_READ (STS; a READ per servo on SCS)
of present position and speed, which is the state the executor records and checks.

Opening: PING every servo, check that its Homing_Offset (STS) is the file's, read where
it is, make that its goal, then torque on: the arm holds where it stands.

Torque policy: on a fault (a servo that does not answer, an arm joint read back farther
than ``max_error`` from the command; not the gripper, which closing on an object stops
short by design) every servo that still listens gets its last read
position as its goal, torque on: the arm stops where it is and holds (an SO-101 let go
falls). ``close`` keeps torque on (``on_close=release`` turns it off). An unplugged
adapter reaches no servo: each holds the last goal it took.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from arduinobot.contract.codes import Code
from arduinobot.description import Description
from arduinobot.execution.robots.base import (
    JointState,
    MimicMap,
    PortNotFound,
    Robot,
    RobotError,
    check_setpoint,
)
from arduinobot.execution.robots.feetech.calibration import (
    InvalidCalibration,
    JointMap,
    joint_maps,
    read_calibration,
)
from arduinobot.execution.robots.feetech.protocol import (
    GOAL_POSITION,
    HOMING_OFFSET,
    PRESENT_POSITION,
    TORQUE_ENABLE,
    FeetechBus,
    Register,
    Series,
    open_bus,
    sign_magnitude,
)
from arduinobot.execution.robots.plugin import DriverSettings

log = logging.getLogger(__name__)

DEFAULT_BAUD = 1_000_000
POSITION_AND_SPEED = Register(PRESENT_POSITION.address, 4)  # one read: 56..59


class TrackingError(RobotError):
    """A joint read back farther from its command than the driver allows."""

    code: str = Code.TRACKING_ERROR


class CalibrationMismatch(RobotError):
    """A servo's Homing_Offset is not the calibration file's: its ticks mean other
    angles than the file says."""

    code: str = Code.CALIBRATION_MISMATCH


def _float_option(options: Mapping[str, str], key: str, default: float) -> float:
    raw = options.get(key)
    if raw is None:
        return default
    try:
        v = float(raw)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise RobotError(f"--driver-option {key}={raw!r}: a positive number",
                         details={"field": f"driver_option.{key}"})
    return v


class FeetechArm(Robot):
    """Servos on one bus, one per actuated joint.

    Args:
        port: the bus adapter (``/dev/ttyACM0``) or a pyserial URL.
        joints: how each actuated joint maps to its servo, the description's order.
        velocity: per-joint velocity limits [rad/s]: one tick never moves a joint
            farther than ``velocity / rate``.
        rate: the control rate [Hz].
        mimic: how the mimic joints follow (reported in the state).
        baud: [bit/s].
        series: ``sts`` (STS/SMS: SYNC_READ, homing offsets) or ``scs``.
        timeout: [s] to wait for a servo's answer.
        max_error: largest |read - commanded| [rad] of an arm joint before
            :class:`TrackingError` stops the arm (the gripper's is not checked: closing
            on an object stops it short of its command by design).
        on_close: ``hold`` keeps torque on at close, ``release`` turns it off.
    """

    realtime_only = True
    feedback = True  # present positions read back from the servos

    def __init__(self, port: str, *, joints: Sequence[JointMap],
                 velocity: Sequence[float] | np.ndarray, rate: float = 100.0,
                 mimic: MimicMap | None = None, baud: int = DEFAULT_BAUD,
                 series: Series = "sts", timeout: float = 0.05, max_error: float = 0.2,
                 on_close: str = "hold") -> None:
        self.joints = tuple(joints)
        self.joint_names = tuple(j.joint for j in self.joints)
        self.mimic = mimic or MimicMap(self.joint_names, (), (), (), ())
        self.state_names = self.mimic.names
        self.ids = [j.servo for j in self.joints]
        self.period = 1.0 / rate
        self.velocity = check_setpoint(velocity, self.joint_names, "velocity limits")
        self.lower = np.array([j.lower for j in self.joints])
        self.upper = np.array([j.upper for j in self.joints])
        self.max_error = max_error
        self._tracked = np.array([j.scale == "degrees" for j in self.joints])
        if on_close not in ("hold", "release"):
            raise RobotError(f"--driver-option on_close={on_close!r}: hold or release",
                             details={"field": "driver_option.on_close"})
        self.on_close = on_close
        self.port = port
        self._commanded: np.ndarray | None = None  # the last goal sent [rad]
        self._read: tuple[np.ndarray, np.ndarray] | None = None  # last q [rad], qd [rad/s]
        self.limited = 0
        self.bus = FeetechBus(open_bus(port, baud), series=series, timeout=timeout, port=port)
        self._opened = time.monotonic()
        try:
            self._start()
        except BaseException:
            self.bus.serial.close()  # type: ignore[attr-defined]
            raise
        log.info("opened %s at %d baud: servos %s, torque on, holding %s", port, baud,
                 self.ids, np.round(self._read[0], 4) if self._read else None)

    @classmethod
    def connect(cls, description: Description, settings: DriverSettings) -> FeetechArm:
        """The driver for ``description`` (the ``--driver feetech`` entry point).

        Options (``--driver-option KEY=VALUE``): ``calibration`` (the LeRobot calibration
        JSON, required), ``gripper`` (joints on the 0-100 scale, comma-separated;
        default the actuated joint named ``gripper``, if any), ``motor.JOINT`` (its motor
        in the file), ``series`` (sts or scs), ``timeout`` [s], ``max_error`` [rad],
        ``on_close`` (hold or release).

        Raises:
            PortNotFound: no ``--port``; InvalidCalibration: no or a bad calibration file.
        """
        from arduinobot.planner.kinematics.limits import JointLimits

        o = dict(settings.options)
        known = {"calibration", "gripper", "series", "timeout", "max_error", "on_close"}
        unknown = [k for k in o if k not in known and not k.startswith("motor.")]
        if unknown:
            raise RobotError(f"--driver-option {unknown[0]}: not a feetech option "
                             f"({', '.join(sorted(known))}, motor.JOINT)",
                             details={"field": f"driver_option.{unknown[0]}"})
        if not settings.port:
            raise PortNotFound("the feetech driver needs --port (the bus adapter: `ls "
                               "/dev/ttyACM* /dev/ttyUSB*` lists the candidates)",
                               details={"field": "port"})
        if "calibration" not in o:
            raise InvalidCalibration("the feetech driver needs --driver-option "
                                     "calibration=FILE (LeRobot's calibration JSON)",
                                     details={"field": "calibration"})
        series = o.get("series", "sts")
        if series not in ("sts", "scs"):
            raise RobotError(f"--driver-option series={series!r}: sts or scs",
                             details={"field": "driver_option.series"})
        mimic = MimicMap.from_description(description)
        lim = JointLimits.from_description(description, joint_names=mimic.actuated)
        default_grip = "gripper" if "gripper" in mimic.actuated else ""
        gripper = [g for g in o.get("gripper", default_grip).split(",") if g]
        motors = {k[len("motor."):]: v for k, v in o.items() if k.startswith("motor.")}
        maps = joint_maps(read_calibration(Path(o["calibration"]).expanduser()),
                          mimic.actuated, lower=lim.lower.tolist(), upper=lim.upper.tolist(),
                          motors=motors,
                          gripper=gripper, resolution=4096 if series == "sts" else 1024)
        return cls(settings.port, joints=maps, velocity=lim.velocity, rate=settings.rate,
                   mimic=mimic, baud=settings.baud or DEFAULT_BAUD,
                   series=series,  # type: ignore[arg-type]  # checked above
                   timeout=_float_option(o, "timeout", 0.05),
                   max_error=_float_option(o, "max_error", 0.2),
                   on_close=o.get("on_close", "hold"))

    # -- opening -----------------------------------------------------------------------
    def _start(self) -> None:
        for j in self.joints:
            self.bus.ping(j.servo)
            if self.bus.series == "sts":
                held = sign_magnitude(self.bus.read_word(j.servo, HOMING_OFFSET), 11)
                if held != j.calibration.homing_offset:
                    raise CalibrationMismatch(
                        f"servo {j.servo} ({j.joint}) holds Homing_Offset {held}, the "
                        f"calibration file says {j.calibration.homing_offset}: calibrate "
                        "again (lerobot-calibrate) or give the file of this arm",
                        details={"servo": j.servo, "joint": j.joint, "servo_offset": held,
                                 "file_offset": j.calibration.homing_offset})
        q, _ = self._read_state()
        self._sync_goal(q)  # the goal is where it stands: torque on moves nothing
        for j in self.joints:
            self.bus.write(j.servo, TORQUE_ENABLE, [1])
        self._commanded = q

    # -- the bus -----------------------------------------------------------------------
    def _sync_goal(self, q: np.ndarray) -> None:
        self.bus.sync_write(GOAL_POSITION, {j.servo: self.bus.word(j.to_ticks(float(v)))
                                            for j, v in zip(self.joints, q)})

    def _read_state(self) -> tuple[np.ndarray, np.ndarray]:
        raw = self.bus.sync_read(POSITION_AND_SPEED, self.ids)
        q, qd = [], []
        for j in self.joints:
            d = raw[j.servo]
            q.append(j.to_joint(sign_magnitude(self.bus.unword(d[:2]), 15)))
            qd.append(j.rate_to_joint(sign_magnitude(self.bus.unword(d[2:]), 15)))
        self._read = (np.array(q), np.array(qd))
        return self._read

    def _hold(self) -> None:
        """After a fault: every servo's goal becomes where it was last read (torque on)."""
        if self._read is None:
            return
        try:
            self._sync_goal(self._read[0])
        except RobotError as e:  # the port itself failed: nothing more can be sent
            log.error("could not send the hold after a fault: %s", e.message)

    # -- Robot -------------------------------------------------------------------------
    def command(self, positions: Sequence[float] | np.ndarray,
                velocities: Sequence[float] | np.ndarray | None = None,
                accelerations: Sequence[float] | np.ndarray | None = None, *,
                jerks: Sequence[float] | np.ndarray | None = None) -> None:
        """One SYNC_WRITE of the goal positions (the servos interpolate themselves: the
        rest of the setpoint is not sent). A goal never moves a joint farther than its
        velocity limit allows in one tick from the last, nor out of its limits."""
        q = check_setpoint(positions, self.joint_names)
        last = self._commanded if self._commanded is not None else q
        step = self.velocity * self.period
        target = np.clip(np.clip(q, last - step, last + step), self.lower, self.upper)
        if np.any(np.abs(target - q) > 1e-9):
            self.limited += 1
            (log.warning if self.limited == 1 else log.debug)(
                "setpoint limited to one tick's motion / the position limits: asked %s, "
                "sending %s (further ones are logged at debug level)", np.round(q, 4),
                np.round(target, 4))
        self._sync_goal(target)
        self._commanded = target

    def advance(self, dt: float) -> None:
        """Hardware keeps its own time: the executor's clock paces the ticks."""

    def state(self) -> JointState:
        """The present positions and speeds read back now.

        Raises:
            ServoNoResponse, ServoFault: a servo did not answer, or reports a fault;
            TrackingError: a joint is farther than ``max_error`` from its command.
            Each after the arm was told to hold where it is.
        """
        try:
            q, qd = self._read_state()
        except RobotError:
            self._hold()
            raise
        if self._commanded is not None:
            gap = np.where(self._tracked, np.abs(q - self._commanded), 0.0)
            worst = int(np.argmax(gap))
            if gap[worst] > self.max_error:
                self._hold()
                j = self.joints[worst]
                raise TrackingError(
                    f"{j.joint} (servo {j.servo}) reads {q[worst]:.4f} rad, commanded "
                    f"{self._commanded[worst]:.4f} rad: |diff| {gap[worst]:.4f} > max_error "
                    f"{self.max_error:g} rad (blocked, overloaded or slipping?); the arm "
                    "holds where it is", details={
                        "joint": j.joint, "servo": j.servo, "read": float(q[worst]),
                        "commanded": float(self._commanded[worst]),
                        "max_error": self.max_error})
        return JointState(self.state_names, tuple(map(float, self.mimic.expand(q))),
                          tuple(map(float, self.mimic.expand(qd, rate=True))), None,
                          time.monotonic() - self._opened)

    def close(self) -> None:
        s = getattr(getattr(self, "bus", None), "serial", None)
        if s is None or not s.is_open:
            return
        try:
            if self.on_close == "release":
                for j in self.joints:
                    self.bus.write(j.servo, TORQUE_ENABLE, [0])
                log.info("torque off on servos %s", self.ids)
        finally:
            s.close()
