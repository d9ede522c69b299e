"""The serial driver against a real pseudo-terminal: every byte the arm would receive is
read back and decoded with the issue's formulas, written out here independently."""

from __future__ import annotations

import math
import os
import re
import select
import shutil
import termios
import threading
import time
import tty

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.description.packages import SHIPPED_PACKAGE_DIR
from arduinobot.execution.executor import ExecuteOptions, Executor
from arduinobot.execution.robots.base import PortBusy, PortError, PortNotFound, UnsupportedRobot
from arduinobot.execution.robots.serial_arduinobot import SerialArduinobot, hardware_params
from arduinobot.execution.segments import SampledTrajectory

MSG = re.compile(rb"b(\d{3}),s(\d{3}),e(\d{3}),g(\d{3}),")
DEG = math.pi / 180


def angles(q):
    """The issue's formulas, verbatim (integer truncation), then the servos' 0..180."""
    q1, q2, q3, q4 = q
    b = int((q1 + math.pi / 2) * 180 / math.pi)
    s = 180 - int((q2 + math.pi / 2) * 180 / math.pi)
    e = int((q3 + math.pi / 2) * 180 / math.pi)
    g = 180 - int((-q4 * 180) / (math.pi / 2))
    return tuple(min(180, max(0, v)) for v in (b, s, e, g))


def decode(a):
    """Joint positions [rad] a message's angles stand for (the lower end of each
    truncation interval)."""
    b, s, e, g = a
    return np.array([b * DEG - math.pi / 2, (180 - s) * DEG - math.pi / 2,
                     e * DEG - math.pi / 2, -(180 - g) * (math.pi / 2) / 180])


class PtyReader:
    """The far end of a pty pair: the slave is the 'Arduino' port, raw mode."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.chunks: list[tuple[float, bytes]] = []
        self._eof = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            r, _, _ = select.select([self.master], [], [], 0.02)
            if r:
                try:
                    data = os.read(self.master, 4096)
                except OSError:  # EIO: every slave end closed and the buffer drained
                    data = b""
                if not data:
                    self._eof.set()
                    return
                self.chunks.append((time.monotonic(), data))

    def received(self) -> int:
        """Messages received so far."""
        return len(MSG.findall(b"".join(c for _, c in list(self.chunks))))

    def wait_for(self, n: int, timeout: float = 60.0) -> None:
        """Until ``n`` messages have arrived (a condition, not a time)."""
        end = time.monotonic() + timeout
        while self.received() < n:
            assert time.monotonic() < end, f"only {self.received()} messages arrived"
            time.sleep(0.005)

    def unplug(self) -> None:
        """The USB cable pulled mid-motion: the far end and the device node vanish."""
        self._stop.set()
        self._thread.join()
        os.close(self.master)
        os.close(self.slave)

    def close(self) -> list[tuple[float, bytes]]:
        """Every chunk the driver wrote: read to the end (the driver closed its side, so
        the master reads EIO once drained)."""
        os.close(self.slave)
        assert self._eof.wait(30), "the port is still held open"
        self._thread.join()
        os.close(self.master)
        return self.chunks


def messages(chunks):
    """(arrival time, angles) per message; the stream must be nothing but messages."""
    data = b"".join(c for _, c in chunks)
    assert MSG.sub(b"", data) == b"", f"stray bytes in the stream: {data[:80]!r}"
    assert b"\n" not in data and b"\r" not in data
    out, pos = [], 0
    ends = np.cumsum([len(c) for _, c in chunks])
    for m in MSG.finditer(data):
        assert m.start() == pos
        pos = m.end()
        t = chunks[int(np.searchsorted(ends, m.end() - 1, side="right"))][0]
        out.append((t, tuple(int(x) for x in m.groups()), m.group(0)))
    return out


class StampedSerial(SerialArduinobot):
    """The driver, noting when (its monotonic clock) it was told to send each message:
    the executor's tick time, before the write itself takes its time."""

    def command(self, positions, velocities=None, accelerations=None, *, jerks=None):
        before, told = self._last, time.monotonic()
        super().command(positions, velocities, accelerations, jerks=jerks)
        if self._last != before:
            self.writes = [*getattr(self, "writes", []), (told, self._last)]


@pytest.fixture(scope="module")
def planned(desc):
    from arduinobot.planner.planning.goals import NamedGoal
    from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
    mp = MotionPlanner(desc)
    res = mp.solve(MotionRequest(goal=NamedGoal("reach_left"), seed=3, sample_rate=100))
    return res.trajectory


def test_bytes_on_the_tty_follow_the_plan_tick_by_tick(desc, planned):
    body = {"trajectory": planned.to_dict()}  # what plan --json writes
    traj = SampledTrajectory.from_json(body)
    pty = PtyReader()
    with StampedSerial.from_description(desc, pty.path, rate=100.0) as robot:
        report = Executor.for_description(robot, desc, options=ExecuteOptions(
            rate=100.0)).execute(traj)
    msgs = messages(pty.close())

    # the ticks: every 10 ms from 0, the last one the final state
    n = math.ceil(planned.duration * 100 - 1e-9)
    tick_t = [min(k / 100, planned.duration) for k in range(n + 1)]
    exact = np.array([planned.at(t).positions for t in tick_t])
    due = [angles(q) for q in exact]
    expected, sent_at = [], []
    for k, a in enumerate(due):
        if not expected or a != expected[-1]:
            expected.append(a)
            sent_at.append(k)
    got = [a for _, a, _ in msgs]
    assert got == expected  # one message per changed tick, none otherwise, nothing else
    assert all(x != y for x, y in zip(got, got[1:]))  # never a resend
    assert got[-1] == angles(planned.positions[-1])  # the final state
    assert all(len(raw) == 20 for _, _, raw in msgs)  # %03d: zero-padded
    assert any(raw.startswith(b"b0") or b",s0" in raw or b",e0" in raw or b",g0" in raw
               for _, _, raw in msgs)  # the padding is exercised (some angle < 100)

    # at every tick, the angles on the arm are within 1 degree of the trajectory
    held = None
    worst = 0.0
    for k in range(n + 1):
        if k in sent_at:
            held = decode(expected[sent_at.index(k)])
        err = np.abs(exact[k] - held)
        worst = max(worst, float(err.max()))
    assert worst < 1 * DEG, f"worst {worst / DEG:.3f} deg"

    # paced: on the driver's own clock, no message goes out before its tick's time (the
    # first may be late by at most what the executor measured): unpaced would be ~0
    writes = robot.writes
    assert [a for _, a in writes] == expected
    span = writes[-1][0] - writes[0][0]
    due_span = (sent_at[-1] - sent_at[0]) / 100
    assert span >= due_span - report.max_lateness, (span, due_span, report.max_lateness)
    assert abs(report.duration - planned.duration) <= 0.01 + 1e-9
    # the arm reports nothing back: every setpoint written, nobody saw it taken
    assert report.outcome == "written"
    print(f"\n{len(msgs)} messages over {span:.3f} s (due {due_span:.3f} s), trajectory "
          f"{planned.duration:.3f} s; worst tick error {worst / DEG:.4f} deg; late ticks "
          f"{report.late_ticks}, max lateness {1000 * report.max_lateness:.1f} ms")


def test_a_jump_is_limited_to_one_ticks_motion_and_angles_clamp(desc):
    pty = PtyReader()
    with SerialArduinobot.from_description(desc, pty.path, rate=100.0) as robot:
        robot.command([1.0, 0.0, 0.0, 0.0])  # 1 rad in one tick: 10 rad/s allows 0.1
        first = robot.state().positions[0]
        robot.command([1.0, 0.0, 0.0, 0.0])
        second = robot.state().positions[0]
        for _ in range(40):
            robot.command([5.0, -5.0, 5.0, -5.0])  # beyond every limit
        last = robot.state()
    msgs = messages(pty.close())
    assert first == pytest.approx(0.1) and second == pytest.approx(0.2)
    assert [a for _, a, _ in msgs][:2] == [angles([0.1, 0, 0, 0]), angles([0.2, 0, 0, 0])]
    assert msgs[-1][1] == (179, 180, 179, 1)  # at the limits (PI = 3.14159 in the xacro)
    assert all(0 <= v <= 180 for _, a, _ in msgs for v in a)
    assert last.names == ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5")
    assert last.positions[4] == pytest.approx(-last.positions[3])  # the mimic follows


def test_missing_and_busy_ports_are_refused_clearly(desc):
    with pytest.raises(PortNotFound, match="does not exist"):
        SerialArduinobot.from_description(desc, "/dev/ttyACM_nothing_here")
    pty = PtyReader()
    try:
        with SerialArduinobot.from_description(desc, pty.path):
            with pytest.raises(PortBusy, match="busy"):
                SerialArduinobot.from_description(desc, pty.path)
    finally:
        pty.close()


def test_the_port_comes_from_the_ros2_control_block(tmp_path):
    pkg = tmp_path / "arduinobot_description"
    shutil.copytree(SHIPPED_PACKAGE_DIR, pkg)
    pty = PtyReader()
    xacro = pkg / "urdf" / "arduinobot.urdf.xacro"
    text = xacro.read_text()
    block = f"""
  <ros2_control name="RobotSystem" type="system">
    <hardware>
      <plugin>arduinobot_controller/ArduinobotInterface</plugin>
      <param name="port">{pty.path}</param>
    </hardware>
    <joint name="joint_1"><command_interface name="position"/></joint>
  </ros2_control>
</robot>"""
    xacro.write_text(text.replace("</robot>", block))
    (pkg / "config" / "initial_positions.yaml").write_text(
        "initial_positions:\n  joint_1: 0.3\n  joint_4: -0.5\n")
    d = load_description(xacro, package_dirs=[tmp_path])
    assert hardware_params(d.robot.urdf)["port"] == pty.path
    with SerialArduinobot.from_description(d) as robot:
        st = robot.state()
        assert robot.port == pty.path
        assert st.positions[:4] == pytest.approx((0.3, 0.0, 0.0, -0.5))  # initial_positions
        robot.command(st.positions[:4])
    msgs = messages(pty.close())
    assert [a for _, a, _ in msgs] == [angles([0.3, 0.0, 0.0, -0.5])]


def test_a_robot_without_four_joints_is_refused(desc):
    with pytest.raises(UnsupportedRobot, match="4 joints"):
        SerialArduinobot("/dev/null", joint_names=["a", "b"], velocity=[1, 1], lower=[0, 0],
                         upper=[1, 1])


def test_execute_cli_streams_to_the_port(planned, tmp_path):
    import json
    import subprocess
    import sys

    from tests.helpers.serve import REPO
    f = tmp_path / "traj.json"
    f.write_text(json.dumps({"trajectory": planned.to_dict()}))
    pty = PtyReader()
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "execute", str(f), "--serial",
                        pty.path, "--boot-wait", "0", "--no-publish"], cwd=REPO,
                       capture_output=True, text=True, timeout=120)
    msgs = messages(pty.close())
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("written") and "reports nothing back" in r.stdout
    assert msgs[-1][1] == angles(planned.positions[-1])
    assert len(msgs) > 50
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "execute", str(f), "--serial",
                        "/dev/ttyACM_nothing_here", "--no-publish"], cwd=REPO,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and "PORT_NOT_FOUND" in r.stderr and "does not exist" in r.stderr


@pytest.mark.slow
def test_serve_drives_the_real_arm_on_its_port(tmp_path):
    import subprocess
    import sys

    from arduinobot.client.client import PlannerClient
    from tests.helpers.serve import REPO, start_server
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "serve", "--listen",
                        "tcp/127.0.0.1:0", "--workers", "1", "--serial",
                        "/dev/ttyACM_nothing_here"], cwd=REPO, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 1 and "PortNotFound" in r.stderr and "does not exist" in r.stderr
    pty = PtyReader()
    srv = start_server(["--workers", "1", "--serial", pty.path, "--boot-wait", "0"])
    try:
        with PlannerClient(srv.endpoint, timeout=30) as c:
            st = c.request("robot_state")
            assert st["name"][:4] == ["joint_1", "joint_2", "joint_3", "joint_4"]
            assert st["position"] == [0.0] * 5 and st["effort"] is None
        run = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "execute", "--remote",
                              "--connect", srv.endpoint, "--named", "reach_forward"],
                             cwd=REPO, capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stderr
    finally:
        srv.stop()
    msgs = messages(pty.close())
    assert msgs[0][1] == angles([0, 0, 0, 0])
    assert msgs[-1][1] == angles([0.0, 0.8, 0.6, 0.0])  # reach_forward


# -- faults the real arm has -------------------------------------------------------------
def _slow(planned):
    """The plan stretched to 4x its duration: long enough to fail in the middle of."""
    return SampledTrajectory(planned.joint_names, planned.times * 4, planned.positions,
                             planned.velocities / 4, planned.accelerations / 16)


def test_the_port_vanishing_mid_motion_stops_with_the_last_setpoint(desc, planned):
    traj = _slow(SampledTrajectory.from_json({"trajectory": planned.to_dict()}))
    pty = PtyReader()
    robot = SerialArduinobot.from_description(desc, pty.path, rate=100.0)
    ex = Executor.for_description(robot, desc, options=ExecuteOptions(rate=100.0))
    failed: list[PortError] = []

    def run() -> None:
        with pytest.raises(PortError) as e:
            ex.execute(traj)
        failed.append(e.value)
    t = threading.Thread(target=run)
    t.start()
    pty.wait_for(20)  # mid-motion
    pty.unplug()
    t.join(30)
    assert not t.is_alive() and failed
    err = failed[0]
    assert err.code == "PORT_ERROR" and "unplugged" in err.message
    d = err.details
    assert d["port"] == pty.path and d["stalled"] is False
    assert 20 <= d["tick"] < math.ceil(traj.duration * 100)
    assert d["phase"] == "trajectory"
    # the last setpoint the arm took is the driver's state: nothing after it counts
    last = np.array([d["last_commanded"][n] for n in robot.joint_names])
    assert last == pytest.approx(robot.state().actuated(robot.joint_names), abs=1e-12)
    assert angles(last) == messages(pty.chunks)[-1][1]  # the last message on the wire
    with pytest.raises(PortError):  # the port stays dead: a new angle cannot go out
        robot.command(last + np.array([0.05, 0.0, 0.0, 0.0]))
    robot.close()


def test_a_write_that_stalls_is_a_coded_failure(desc, planned):
    traj = SampledTrajectory.from_json({"trajectory": planned.to_dict()})
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    # the arm stopped reading: the port takes no byte, so the first write blocks. Output
    # held on the tty, not its buffer filled: a pty hands written bytes to its far end in
    # the background and frees room later (found by a write retried after its timeout),
    # so a filled buffer does not stay full.
    termios.tcflow(slave, termios.TCOOFF)
    try:
        with SerialArduinobot.from_description(desc, path, rate=100.0) as robot:
            start = robot.state().actuated(robot.joint_names)
            ex = Executor.for_description(robot, desc, options=ExecuteOptions(rate=100.0))
            with pytest.raises(PortError) as e:
                ex.execute(traj)
            d = e.value.details
            assert d["stalled"] is True and "stalled" in e.value.message
            assert d["tick"] == 0 and d["last_sent"] is None
            # nothing went through: the arm holds where it was
            assert [d["last_commanded"][n] for n in robot.joint_names] == \
                pytest.approx(start.tolist())
    finally:
        for fd in (slave, master):
            os.close(fd)


def test_an_arm_that_stops_reading_is_caught_within_a_few_messages(desc, planned):
    """A USB device that stops reading mid-motion (its port queues what it does not take,
    as CDC-ACM does): the driver stops once the backlog has not drained for 30 ms (a few
    ticks; a port flushing late on a busy machine is not a stall), long before the
    port's buffer (4 KB: two hundred messages) would fill and a write would block."""
    import serial

    from tests.helpers.protocol_stalling import DEVICES, Device
    if "tests.helpers" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("tests.helpers")
    dev = DEVICES["arm"] = Device()
    traj = _slow(SampledTrajectory.from_json({"trajectory": planned.to_dict()}))

    class Stalling(SerialArduinobot):
        def command(self, positions, velocities=None, accelerations=None, *, jerks=None):
            if len(dev.received) == 30:  # mid-motion, the far end stops reading
                dev.reading = False
            super().command(positions, velocities, accelerations, jerks=jerks)

    robot = Stalling.from_description(desc, "stalling://arm", rate=100.0)
    ex = Executor.for_description(robot, desc, options=ExecuteOptions(rate=100.0))
    with pytest.raises(PortError) as e:
        ex.execute(traj)
    d = e.value.details
    assert e.value.code == "PORT_ERROR" and d["stalled"] is True
    assert "the arm stopped reading" in e.value.message
    queued = dev.writes - len(dev.received)
    assert 3 <= queued <= 12, queued  # a few ticks' messages, not the buffer's 200
    assert d["unsent"] == queued * len(b"b000,s000,e000,g000,")
    assert d["tick"] < math.ceil(traj.duration * 100) and d["phase"] == "trajectory"
    # the error names the last message written (queued, not taken), and the arm holds
    # the last one it read, from before
    def ints(m):
        return [int(x) for x in MSG.fullmatch(m).groups()]
    assert d["last_sent"] == ints(dev.written[-1]) != ints(dev.received[-1])
    robot.close()


def test_a_line_too_slow_for_the_rate_is_refused_not_left_to_lag(desc, planned):
    """At 1200 baud a 20-byte message takes 167 ms: at 100 Hz the commands would fall
    further behind every tick; the driver stops once one would arrive 2 ticks late."""
    import serial

    from tests.helpers.protocol_stalling import DEVICES, Device
    if "tests.helpers" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("tests.helpers")
    DEVICES["slow"] = Device(reading=False)  # the bytes drain at the line's pace: never
    robot = SerialArduinobot.from_description(desc, "stalling://slow", rate=100.0, baud=1200)
    with pytest.raises(PortError, match="too slow for 100 Hz") as e:
        for i in range(200):  # ticks, paced as the executor paces them
            robot.command([0.02 * i, 0.0, 0.0, 0.0])
            time.sleep(0.01)
    assert e.value.details["unsent"] >= 20 and i >= 1  # once the lag lasted 30 ms
    robot.close()


def test_a_port_that_never_opens_is_a_coded_failure(desc):
    import fcntl
    import struct
    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.close(slave)
    # the device node is there, but the device refuses every open (EIO), as a board
    # that enumerates and then hangs: the pty's slave locked (TIOCSPTLCK)
    fcntl.ioctl(master, 0x40045431, struct.pack("i", 1))
    try:
        assert os.path.exists(path)
        with pytest.raises(PortError, match="cannot open serial port") as e:
            SerialArduinobot.from_description(desc, path)
        assert e.value.code == "PORT_ERROR" and e.value.details["port"] == path
    finally:
        os.close(master)


@pytest.mark.slow
def test_the_service_keeps_serving_after_the_arm_is_unplugged(planned):
    from arduinobot.client.client import PlannerClient
    from arduinobot.client.errors import ServiceError
    from tests.helpers.serve import start_server
    pty = PtyReader()
    srv = start_server(["--workers", "1", "--serial", pty.path, "--boot-wait", "0"])
    try:
        with PlannerClient(srv.endpoint, timeout=30) as c:
            failed: list[ServiceError] = []

            def run() -> None:
                with pytest.raises(ServiceError) as e:
                    c.execute(plan={"goal": {"named": "reach_forward"},
                                    "velocity_scaling": 0.2, "acceleration_scaling": 0.2})
                failed.append(e.value)
            t = threading.Thread(target=run)
            t.start()
            pty.wait_for(20)
            pty.unplug()
            t.join(60)
            assert failed and failed[0].code == "PORT_ERROR", failed
            d = failed[0].details
            assert set(d["last_commanded"]) == {"joint_1", "joint_2", "joint_3", "joint_4"}
            assert d["tick"] >= 20 and d["phase"] == "trajectory"
            # planning goes on; the arm is gone: asking for it is a coded refusal, and
            # the service still answers afterwards
            assert c.plan(goal={"named": "reach_right"}).duration > 0
            with pytest.raises(ServiceError) as e:
                c.robot_state()
            assert e.value.code == "PORT_NOT_FOUND" and pty.path in e.value.message
            assert c.health()["instance"] == srv.instance
            assert c.plan(goal={"named": "reach_left"}).duration > 0
    finally:
        srv.stop()
