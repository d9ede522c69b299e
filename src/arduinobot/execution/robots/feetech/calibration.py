"""A LeRobot calibration file, read as LeRobot writes it, and joint angles <-> servo ticks.

LeRobot (``lerobot-calibrate``) saves one JSON object per arm, a motor per key::

    {"shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": -1470,
                      "range_min": 758, "range_max": 3292}, ...}

``homing_offset`` is what calibration wrote into the servo's own Homing_Offset register
(so its Present_Position reads ``raw - homing_offset``); ``range_min``/``range_max`` are
the homed ticks the joint can reach; ``drive_mode`` 1 turns the direction around. How
ticks become joint values follows LeRobot's normalisation (``MotorsBus._normalize``):

- an arm joint (LeRobot's ``degrees`` mode, which the SO-101's ``so101_new_calib.urdf``
  is drawn for): ``q = s * (ticks - mid) * 2 pi / (resolution - 1)`` [rad], ``mid`` the
  middle of the range, ``s`` -1 with ``drive_mode`` 1 (LeRobot's degrees ignore
  drive_mode; the SO-101's are all 0, where both agree);
- the gripper (LeRobot's ``range_0_100``): ``pct = 100 (ticks - min) / (max - min)``
  (``100 - pct`` with drive_mode 1), laid linearly onto the URDF joint's
  ``[lower, upper]`` [rad]: 0 (closed) at ``lower``, 100 (open) at ``upper``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from arduinobot.contract.codes import Code
from arduinobot.execution.robots.base import RobotError

Scale = Literal["degrees", "range_0_100"]
FIELDS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")


class InvalidCalibration(RobotError):
    """The calibration file is missing, unreadable, or does not fit the robot."""

    code: str = Code.INVALID_CALIBRATION


@dataclass(frozen=True)
class MotorCalibration:
    """One motor's entry of the file (LeRobot's ``MotorCalibration``), ticks."""

    id: int
    drive_mode: int
    homing_offset: int
    range_min: int
    range_max: int


def read_calibration(path: str | Path) -> dict[str, MotorCalibration]:
    """The motors of a LeRobot calibration file, by name.

    Raises:
        InvalidCalibration: no such file, not JSON, or an entry missing a field, with a
            non-integer value, or with ``range_min >= range_max``.
    """
    p = Path(path)
    try:
        raw = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise InvalidCalibration(f"calibration file {p}: {e}",
                                 details={"field": "calibration", "path": str(p)}) from None
    if not isinstance(raw, dict) or not raw:
        raise InvalidCalibration(f"calibration file {p}: not an object of motors "
                                 "(LeRobot's {\"name\": {\"id\": ...}})",
                                 details={"field": "calibration", "path": str(p)})
    out: dict[str, MotorCalibration] = {}
    for name, entry in raw.items():
        where = f"{name}"
        missing = [f for f in FIELDS if not isinstance(entry, dict) or f not in entry]
        if missing:
            raise InvalidCalibration(f"calibration file {p}: motor '{name}' has no "
                                     f"{', '.join(missing)}",
                                     details={"field": where, "path": str(p)})
        bad = [f for f in FIELDS if type(entry[f]) is not int]
        if bad:
            raise InvalidCalibration(f"calibration file {p}: motor '{name}': "
                                     f"{', '.join(bad)} must be integers",
                                     details={"field": f"{where}.{bad[0]}", "path": str(p)})
        cal = MotorCalibration(*(entry[f] for f in FIELDS))
        if cal.range_min >= cal.range_max:
            raise InvalidCalibration(f"calibration file {p}: motor '{name}': range_min "
                                     f"{cal.range_min} >= range_max {cal.range_max}",
                                     details={"field": f"{where}.range_min", "path": str(p)})
        out[name] = cal
    ids = [c.id for c in out.values()]
    if len(set(ids)) != len(ids):
        raise InvalidCalibration(f"calibration file {p}: two motors share an id ({ids})",
                                 details={"field": "id", "path": str(p)})
    return out


@dataclass(frozen=True)
class JointMap:
    """How one joint's angle maps to its servo's ticks.

    Attributes:
        joint: the URDF joint; motor: its name in the calibration file.
        calibration: the motor's entry.
        scale: ``degrees`` (an arm joint) or ``range_0_100`` (the gripper).
        lower, upper: the joint's position limits [rad] (the gripper's 0 and 100).
        resolution: ticks per turn (4096 on an STS3215, 1024 on SCS servos).
    """

    joint: str
    motor: str
    calibration: MotorCalibration
    scale: Scale
    lower: float
    upper: float
    resolution: int = 4096

    @property
    def servo(self) -> int:
        return self.calibration.id

    @property
    def _sign(self) -> float:
        return -1.0 if self.calibration.drive_mode else 1.0

    def to_ticks(self, q: float) -> int:
        """The goal ticks of joint value ``q`` [rad], within the calibrated range."""
        c = self.calibration
        if self.scale == "degrees":
            mid = (c.range_min + c.range_max) / 2
            t = mid + self._sign * q * (self.resolution - 1) / (2 * math.pi)
        else:
            pct = 100.0 * (q - self.lower) / (self.upper - self.lower)
            pct = 100.0 - pct if c.drive_mode else pct
            t = c.range_min + pct / 100.0 * (c.range_max - c.range_min)
        return int(min(c.range_max, max(c.range_min, round(t))))

    def to_joint(self, ticks: float) -> float:
        """The joint value [rad] of present position ``ticks``."""
        c = self.calibration
        if self.scale == "degrees":
            mid = (c.range_min + c.range_max) / 2
            return self._sign * (ticks - mid) * 2 * math.pi / (self.resolution - 1)
        pct = 100.0 * (ticks - c.range_min) / (c.range_max - c.range_min)
        pct = 100.0 - pct if c.drive_mode else pct
        return self.lower + pct / 100.0 * (self.upper - self.lower)

    def rate_to_joint(self, ticks_per_s: float) -> float:
        """A speed [ticks/s] as the joint's [rad/s]."""
        c = self.calibration
        if self.scale == "degrees":
            return self._sign * ticks_per_s * 2 * math.pi / (self.resolution - 1)
        s = (self.upper - self.lower) / (c.range_max - c.range_min)
        return -s * ticks_per_s if c.drive_mode else s * ticks_per_s


def joint_maps(calibration: Mapping[str, MotorCalibration], joints: Sequence[str], *,
               lower: Sequence[float], upper: Sequence[float],
               motors: Mapping[str, str] | None = None,
               gripper: Sequence[str] = (), resolution: int = 4096) -> tuple[JointMap, ...]:
    """One :class:`JointMap` per joint of ``joints``: its motor is ``motors[joint]``,
    else the motor of the same name (the SO-101's URDF and LeRobot name them alike);
    the ``gripper`` joints use the 0-100 scale.

    Raises:
        InvalidCalibration: a joint without a motor in the file.
    """
    motors = dict(motors or {})
    out = []
    for j, lo, hi in zip(joints, lower, upper):
        m = motors.get(j, j)
        if m not in calibration:
            raise InvalidCalibration(
                f"joint '{j}' has no motor '{m}' in the calibration file (motors: "
                f"{', '.join(calibration)}); name it with --driver-option motor.{j}=NAME",
                details={"field": f"motor.{j}", "joint": j})
        scale: Scale = "range_0_100" if j in gripper else "degrees"
        out.append(JointMap(j, m, calibration[m], scale, float(lo), float(hi), resolution))
    return tuple(out)
