"""Which robot to open: the real arm on a serial port, the MuJoCo twin, a plug-in driver
(:mod:`arduinobot.execution.robots.plugin`), or none.

The command line (``execute --serial/--sim/--driver``) and the service (``serve --serial``,
``--driver``, ``--no-robot``) both describe their robot with a :class:`RobotSpec` and open it here, so
neither goes through the other to reach a driver.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from arduinobot.description import Description
from arduinobot.execution.robots.base import (
    JointState,
    MimicMap,
    Robot,
    RobotError,
    initial_positions,
)
from arduinobot.execution.robots.mjcf import Progress
from arduinobot.planner.cache import ArtifactCache

RobotKind = Literal["sim", "serial", "driver", "none"]


@dataclass(frozen=True)
class RobotSpec:
    """The robot to drive.

    Attributes:
        kind: ``sim`` (MuJoCo twin), ``serial`` (the real arm), ``driver`` (a plug-in
            driver) or ``none``.
        port, baud: the serial port (None: the URDF's ros2_control ``port``; a plug-in
            driver's default) and baud.
        driver: ``module:Class`` or an ``arduinobot.drivers`` entry point's name.
        driver_options: its ``--driver-option KEY=VALUE`` pairs.
        rate: control rate [Hz].
        boot_wait: [s] to wait after opening the port (the Arduino resets).
        cache: the twin's mesh pieces kept between runs (see
            :func:`arduinobot.execution.robots.mjcf.mesh_parts`).
        progress: told what a first twin of a new model is building (seconds per mesh).
    """

    kind: RobotKind = "sim"
    port: str | None = None
    baud: int | None = None
    rate: float = 100.0
    boot_wait: float = 2.0
    driver: str | None = None
    driver_options: tuple[tuple[str, str], ...] = ()
    cache: ArtifactCache | None = field(default=None, compare=False, repr=False)
    progress: Progress | None = field(default=None, compare=False, repr=False)

    def open(self, description: Description, *,
             obstacles: Sequence[Mapping[str, Any]] = ()) -> Robot:
        """The driver: the real arm (its port opened), a plug-in driver, or the twin
        among ``obstacles``.

        Raises:
            RobotError: kind ``none``, or the port's error (PortNotFound, PortBusy, ...);
                DriverNotFound, NotADriver or the plug-in's own errors.
        """
        if self.kind == "serial":
            from arduinobot.execution.robots.serial_arduinobot import SerialArduinobot
            return SerialArduinobot.from_description(description, self.port, baud=self.baud,
                                                     rate=self.rate, boot_wait=self.boot_wait)
        if self.kind == "driver" and self.driver:
            from arduinobot.execution.robots.plugin import DriverSettings, connect
            return connect(self.driver, description, DriverSettings(
                port=self.port, baud=self.baud, rate=self.rate,
                options=dict(self.driver_options)))
        if self.kind == "sim":
            from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
            return SimArduinobot(description, obstacles=obstacles, cache=self.cache,
                                 progress=self.progress)
        # details.robot: what the kept scene reads as "no robot state" (all joints 0)
        raise RobotError("this service drives no robot (serve --no-robot)",
                         details={"robot": "none"})


def twin_start(description: Description) -> JointState:
    """The twin's state before it is opened: where it starts (``initial_positions.yaml``'s,
    else 0, the mimic joints following), at rest, at its clock's zero; efforts unknown.
    Said without building it (MuJoCo on a model's CAD meshes takes seconds)."""
    mimic = MimicMap.from_description(description)
    q = mimic.expand(initial_positions(description, mimic.actuated))
    return JointState(mimic.names, tuple(map(float, q)), (0.0,) * len(q), None, 0.0)
