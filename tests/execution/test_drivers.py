"""Plug-in drivers: ``--driver module:Class`` and the ``arduinobot.drivers`` entry points,
as a user writes one (a plain class in a module of their own, not a Robot subclass), and
the clear errors for a module that does not import or a class that is not a driver."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from arduinobot.cli.main import main
from arduinobot.description import load_description
from arduinobot.execution.robots.base import Robot
from arduinobot.execution.robots.plugin import (
    BUILTIN,
    DriverNotFound,
    DriverSettings,
    NotADriver,
    load_driver,
)
from arduinobot.execution.robots.spec import RobotSpec

ROOT = Path(__file__).resolve().parents[2]

# a user's driver, as docs/drivers.md tells them to write one: a class with connect()
USER_DRIVER = '''
import time

from arduinobot.execution.robots.base import JointState, MimicMap

LOG = []  # what the driver was told, for the test to read


class ListArm:
    realtime_only = True

    def __init__(self, mimic, options):
        self.mimic = mimic
        self.joint_names = mimic.actuated
        self.state_names = mimic.names
        self.options = options
        self.q = [0.0] * len(self.joint_names)
        self.t0 = time.monotonic()

    @classmethod
    def connect(cls, description, settings):
        LOG.append(("connect", settings.port, dict(settings.options), settings.rate))
        return cls(MimicMap.from_description(description), settings.options)

    def command(self, positions, velocities=None, accelerations=None, *, jerks=None):
        self.q = [float(v) for v in positions]
        LOG.append(("command", self.q))

    def advance(self, dt):
        pass

    def state(self):
        q = self.mimic.expand(self.q)
        return JointState(self.state_names, tuple(map(float, q)), (0.0,) * len(q), None,
                          time.monotonic() - self.t0)

    def close(self):
        LOG.append(("close",))


class NoState:
    @classmethod
    def connect(cls, description, settings):
        return cls()

    def command(self, positions): ...
    def advance(self, dt): ...
    def close(self): ...


class ReturnsNothing(ListArm):
    @classmethod
    def connect(cls, description, settings):
        return object()


def not_a_class(description, settings):
    return None
'''


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    (tmp_path / "userarm.py").write_text(USER_DRIVER)
    (tmp_path / "brokenarm.py").write_text("import no_such_package_for_arms\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    for m in ("userarm", "brokenarm"):
        sys.modules.pop(m, None)


def test_a_users_driver_runs_a_trajectory_from_the_command_line(tmp_path, user_module):
    traj = tmp_path / "traj.json"
    points = [{"time_from_start": t, "positions": [0.1 * t, -0.1 * t, 0.05 * t, -0.2 * t]}
              for t in np.arange(0, 51) / 100]
    traj.write_text(json.dumps({"trajectory": {
        "joint_names": ["joint_1", "joint_2", "joint_3", "joint_4"], "points": points}}))
    out = tmp_path / "r.json"
    code = main(["execute", str(traj), "--driver", "userarm:ListArm", "--port", "sim0",
                 "--driver-option", "speed=slow", "--no-publish", "--report", str(out)])
    assert code == 0
    import userarm
    assert userarm.LOG[0] == ("connect", "sim0", {"speed": "slow"}, 100.0)
    commands = [e[1] for e in userarm.LOG if e[0] == "command"]
    r = json.loads(out.read_text())
    # its state is the last command (no feedback attribute): played whole, not seen
    assert len(commands) == r["ticks"] and r["outcome"] == "written"
    assert np.allclose(commands[-1], points[-1]["positions"])
    assert userarm.LOG[-1] == ("close",)


def test_a_plain_class_comes_back_as_a_robot(user_module):
    desc = load_description()
    robot = RobotSpec(kind="driver", driver="userarm:ListArm").open(desc)
    with robot:
        assert isinstance(robot, Robot)
        robot.command([0.1, 0.2, 0.3, -0.4])
        assert robot.state().positions[:4] == (0.1, 0.2, 0.3, -0.4)
        assert robot.state_names[-1] == "joint_5"  # the mimic joint, from the driver


@pytest.mark.parametrize(("spec", "error", "said"), [
    ("no_such_module_for_arms:Arm", DriverNotFound, "does not import: ModuleNotFoundError"),
    ("brokenarm:Arm", DriverNotFound, "no_such_package_for_arms"),
    ("userarm:Missing", DriverNotFound, "has no 'Missing'"),
    ("userarm", DriverNotFound, "no driver of that name"),
    ("userarm:", DriverNotFound, "module:Class"),
    ("userarm:not_a_class", NotADriver, "not a class"),
    ("userarm:NoState", NotADriver, "it has no state"),
])
def test_what_is_not_a_driver_is_said_clearly(user_module, spec, error, said):
    with pytest.raises(error) as e:
        load_driver(spec)
    assert said in e.value.message and spec in e.value.message
    assert e.value.code == ("DRIVER_NOT_FOUND" if error is DriverNotFound else "NOT_A_DRIVER")
    assert e.value.details["field"] == "driver"


def test_connect_returning_a_non_driver_is_refused(user_module):
    with pytest.raises(NotADriver) as e:
        RobotSpec(kind="driver", driver="userarm:ReturnsNothing").open(load_description())
    assert "joint_names" in e.value.details["missing"]


def test_the_command_line_exits_1_with_the_code(user_module, tmp_path, capsys):
    traj = tmp_path / "t.json"
    traj.write_text(json.dumps({"trajectory": {"joint_names": ["joint_1"], "points": [
        {"time_from_start": 0, "positions": [0.0]}]}}))
    assert main(["execute", str(traj), "--driver", "brokenarm:Arm", "--no-publish"]) == 1
    err = capsys.readouterr().err
    assert "DRIVER_NOT_FOUND" in err and "no_such_package_for_arms" in err
    with pytest.raises(SystemExit) as ex:  # --port without --driver: a usage error
        main(["execute", str(traj), "--sim", "--port", "/dev/ttyACM0"])
    assert ex.value.code == 2 and "go with --driver" in capsys.readouterr().err


def test_feetech_is_a_driver_by_name_and_its_entry_point_is_registered():
    from arduinobot.execution.robots.feetech.driver import FeetechArm
    assert load_driver("feetech") is FeetechArm
    text = (ROOT / "pyproject.toml").read_text("utf-8")
    block = text.split('[project.entry-points."arduinobot.drivers"]', 1)[1].split("\n[", 1)[0]
    registered = dict(re.findall(r'^(\w+) = "([^"]+)"', block, flags=re.M))
    assert registered == BUILTIN
    assert DriverSettings().rate == 100.0


def test_the_example_in_docs_drivers_md_runs(tmp_path, monkeypatch, capsys):
    text = (ROOT / "docs" / "drivers.md").read_text("utf-8")
    code = re.search(r"```python\n(.*?)```", text, flags=re.S).group(1)
    (tmp_path / "docsarm.py").write_text(code)
    monkeypatch.syspath_prepend(str(tmp_path))
    traj = tmp_path / "t.json"
    traj.write_text(json.dumps({"trajectory": {"joint_names": ["joint_1", "joint_2"],
                                               "points": [
        {"time_from_start": 0, "positions": [0.0, 0.0]},
        {"time_from_start": 0.2, "positions": [0.02, -0.02]}]}}))
    try:
        assert main(["execute", str(traj), "--driver", "docsarm:MyArm", "--no-publish"]) == 1
        assert "needs --port" in capsys.readouterr().err  # its own RobotError, coded
        assert main(["execute", str(traj), "--driver", "docsarm:MyArm", "--port", "x",
                     "--no-publish"]) == 0
        assert capsys.readouterr().out.startswith("written")
    finally:
        sys.modules.pop("docsarm", None)
