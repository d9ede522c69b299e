"""Drivers a user plugs in: ``execute --driver module:Class``, ``serve --driver NAME``.

A driver is a class with a ``connect(description, settings)`` classmethod that returns
an object doing what :class:`~arduinobot.execution.robots.base.Robot` does (the
:class:`Driver` protocol: ``joint_names``, ``state_names``, ``realtime_only``,
``command``, ``advance``, ``state``, ``close``). Subclassing ``Robot`` is the easy way,
not a requirement. ``--driver`` names it as ``package.module:Class`` or by a name of the
``arduinobot.drivers`` entry-point group (``feetech`` is ours). How to write one:
docs/drivers.md.
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any, Protocol, runtime_checkable

import numpy as np

from arduinobot.contract.codes import Code
from arduinobot.description import Description
from arduinobot.execution.robots.base import JointState, Robot, RobotError

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "arduinobot.drivers"
#: the drivers this package ships, as pyproject.toml registers them (found by name even
#: when the package runs from a source tree without its metadata)
BUILTIN: dict[str, str] = {"feetech": "arduinobot.execution.robots.feetech.driver:FeetechArm"}


class DriverNotFound(RobotError):
    """``--driver`` names a module that does not import, or no such class in it."""

    code: str = Code.DRIVER_NOT_FOUND


class NotADriver(RobotError):
    """``--driver`` names something that is not a driver (no ``connect``, or missing
    what a robot does)."""

    code: str = Code.NOT_A_DRIVER


@runtime_checkable
class Driver(Protocol):
    """What the executor needs of a robot (:class:`~arduinobot.execution.robots.base.Robot`
    says what each does)."""

    joint_names: tuple[str, ...]
    state_names: tuple[str, ...]
    realtime_only: bool

    def command(self, positions: Sequence[float] | np.ndarray,
                velocities: Sequence[float] | np.ndarray | None = None,
                accelerations: Sequence[float] | np.ndarray | None = None, *,
                jerks: Sequence[float] | np.ndarray | None = None) -> None: ...

    def advance(self, dt: float) -> None: ...

    def state(self) -> JointState: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class DriverSettings:
    """What the command line hands a driver's ``connect``.

    Attributes:
        port: ``--port`` (None: the driver's default or its config's).
        baud: ``--baud`` [bit/s] (None: the driver's default).
        rate: the control rate [Hz]: ``command`` is called this often.
        options: ``--driver-option KEY=VALUE``, as strings (the driver parses them).
    """

    port: str | None = None
    baud: int | None = None
    rate: float = 100.0
    options: Mapping[str, str] = field(default_factory=dict)


class DriverClass(Protocol):
    """A driver class: ``connect`` opens the hardware for ``description``."""

    @classmethod
    def connect(cls, description: Description, settings: DriverSettings) -> Driver: ...


_METHODS = ("command", "advance", "state", "close")


def _resolve(spec: str) -> tuple[str, str]:
    """``module:Class`` of ``spec``: as given, a built-in, or an entry point's value."""
    if ":" in spec:
        mod, _, name = spec.partition(":")
        if not mod or not name:
            raise DriverNotFound(f"--driver {spec!r}: write it module:Class "
                                 "(e.g. mypkg.arm:MyArm)", details={"field": "driver"})
        return mod, name
    found = {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}
    target = found.get(spec) or BUILTIN.get(spec)
    if target is None:
        known = sorted(set(found) | set(BUILTIN))
        raise DriverNotFound(f"--driver {spec!r}: no driver of that name in the "
                             f"'{ENTRY_POINT_GROUP}' entry points ({', '.join(known)}); or "
                             "give module:Class", details={"field": "driver",
                                                           "known": known})
    mod, _, name = target.partition(":")
    return mod, name


def load_driver(spec: str) -> type[Any]:
    """The driver class ``spec`` names (``module:Class`` or an entry point's name).

    Raises:
        DriverNotFound: the module does not import, or has no such attribute.
        NotADriver: it is not a class with ``connect`` and the robot's methods.
    """
    mod_name, cls_name = _resolve(spec)
    try:
        mod = importlib.import_module(mod_name)
    except Exception as e:  # any import-time failure is the user's module's, reported whole
        raise DriverNotFound(f"--driver {spec!r}: module '{mod_name}' does not import: "
                             f"{type(e).__name__}: {e}",
                             details={"field": "driver", "module": mod_name}) from e
    obj = mod
    for part in cls_name.split("."):
        if not hasattr(obj, part):
            raise DriverNotFound(f"--driver {spec!r}: module '{mod_name}' has no "
                                 f"'{cls_name}'", details={"field": "driver",
                                                           "module": mod_name})
        obj = getattr(obj, part)
    if not isinstance(obj, type):
        raise NotADriver(f"--driver {spec!r}: '{cls_name}' is a {type(obj).__name__}, not "
                         "a class", details={"field": "driver"})
    missing = [m for m in ("connect", *_METHODS) if not callable(getattr(obj, m, None))]
    if missing:
        raise NotADriver(f"--driver {spec!r}: {obj.__qualname__} is not a driver: it has no "
                         f"{', '.join(missing)} (see docs/drivers.md)",
                         details={"field": "driver", "missing": missing})
    return obj


class _Adapted(Robot):
    """A :class:`Driver` that is not a :class:`Robot` subclass, as one (a context
    manager, as the executor's callers use robots)."""

    def __init__(self, driver: Driver) -> None:
        self.driver = driver
        self.joint_names = tuple(driver.joint_names)
        self.state_names = tuple(driver.state_names)
        self.realtime_only = bool(driver.realtime_only)
        self.feedback = bool(getattr(driver, "feedback", False))

    def command(self, positions: Sequence[float] | np.ndarray,
                velocities: Sequence[float] | np.ndarray | None = None,
                accelerations: Sequence[float] | np.ndarray | None = None, *,
                jerks: Sequence[float] | np.ndarray | None = None) -> None:
        self.driver.command(positions, velocities, accelerations, jerks=jerks)

    def advance(self, dt: float) -> None:
        self.driver.advance(dt)

    def state(self) -> JointState:
        return self.driver.state()

    def close(self) -> None:
        self.driver.close()


def connect(spec: str, description: Description, settings: DriverSettings) -> Robot:
    """Open the driver ``spec`` names for ``description`` (a :class:`Driver` that does not
    subclass :class:`Robot` comes back wrapped in one).

    Raises:
        DriverNotFound, NotADriver: as :func:`load_driver`; NotADriver too when
            ``connect`` returns something without the robot's attributes and methods.
        RobotError: the driver's own errors (a port, a servo), as it raises them.
    """
    cls = load_driver(spec)
    robot = cls.connect(description, settings)
    if not isinstance(robot, Driver):
        missing = [a for a in ("joint_names", "state_names", "realtime_only", *_METHODS)
                   if not hasattr(robot, a)]
        if hasattr(robot, "close"):
            robot.close()
        raise NotADriver(f"--driver {spec!r}: {cls.__qualname__}.connect returned a "
                         f"{type(robot).__name__} without {', '.join(missing)}",
                         details={"field": "driver", "missing": missing})
    log.info("driver %s: %s", spec, ", ".join(robot.joint_names))
    return robot if isinstance(robot, Robot) else _Adapted(robot)
