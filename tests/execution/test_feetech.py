"""The Feetech bus driver on a pty against tests/helpers/feetech_bus.py, a simulated STS
bus written from the servos' manual: the trajectory reaches its goals in ticks, and the
failures (unplugged, a silent servo, a blocked joint, a wrong calibration) are coded and
leave the arm holding where it is."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from arduinobot.cli.main import main
from arduinobot.description import load_description
from arduinobot.execution.executor import ExecuteOptions, Executor
from arduinobot.execution.robots.base import PortError, PortNotFound, RobotError
from arduinobot.execution.robots.feetech.calibration import InvalidCalibration
from arduinobot.execution.robots.feetech.driver import (
    CalibrationMismatch,
    FeetechArm,
    TrackingError,
)
from arduinobot.execution.robots.feetech.protocol import ServoFault, ServoNoResponse
from arduinobot.execution.robots.plugin import DriverSettings
from arduinobot.execution.segments import SampledTrajectory
from tests.helpers.feetech_bus import SimBus

# the shipped arduinobot as a bus arm: joint_1..3 on servos 1..3, the gripper joint_4 on
# servo 4 (0-100 scale); joint_2 and the gripper turn the other way (drive_mode 1)
CALIBRATION = {
    "joint_1": {"id": 1, "drive_mode": 0, "homing_offset": -1470, "range_min": 900,
                "range_max": 3100},
    "joint_2": {"id": 2, "drive_mode": 1, "homing_offset": 0, "range_min": 900,
                "range_max": 3100},
    "joint_3": {"id": 3, "drive_mode": 0, "homing_offset": 312, "range_min": 900,
                "range_max": 3100},
    "joint_4": {"id": 4, "drive_mode": 1, "homing_offset": 25, "range_min": 2000,
                "range_max": 3000},
}
HOMING = {c["id"]: c["homing_offset"] for c in CALIBRATION.values()}
GRIPPER_LOWER, GRIPPER_UPPER = -1.570795, 0.0  # joint_4's URDF limits


def expected_ticks(joint: str, q: float) -> float:
    """LeRobot's unnormalisation, spelled out: degrees about the range's middle
    (resolution 4096) for the arm, the 0-100 scale for the gripper (0 at the URDF's
    lower limit); drive_mode 1 turns the direction."""
    c = CALIBRATION[joint]
    lo, hi, flip = c["range_min"], c["range_max"], c["drive_mode"] == 1
    if joint == "joint_4":
        pct = 100 * (q - GRIPPER_LOWER) / (GRIPPER_UPPER - GRIPPER_LOWER)
        pct = 100 - pct if flip else pct
        return pct / 100 * (hi - lo) + lo
    deg = math.degrees(q)
    return (-deg if flip else deg) * 4095 / 360 + (lo + hi) / 2


def at_zero() -> dict[int, int]:
    return {c["id"]: round(expected_ticks(j, 0.0)) for j, c in CALIBRATION.items()}


@pytest.fixture(scope="module")
def desc():
    return load_description()


@pytest.fixture
def cal_file(tmp_path):
    p = tmp_path / "arm.json"
    p.write_text(json.dumps(CALIBRATION))
    return p


@pytest.fixture(scope="module")
def planned():
    """A 1.5 s quintic rest-to-rest move of every joint (the gripper half closed), at
    100 Hz: well within the arduinobot's 10 rad/s."""
    goal = np.array([0.6, -0.4, 0.5, -0.8])
    t = np.arange(151) / 100
    s = t / 1.5
    p = 10 * s**3 - 15 * s**4 + 6 * s**5
    v = (30 * s**2 - 60 * s**3 + 30 * s**4) / 1.5
    a = (60 * s - 180 * s**2 + 120 * s**3) / 1.5**2
    return SampledTrajectory(("joint_1", "joint_2", "joint_3", "joint_4"), t,
                             np.outer(p, goal), np.outer(v, goal), np.outer(a, goal))


def settings(bus: SimBus, cal, **extra: str) -> DriverSettings:
    # timeout 2 s: the simulated bus is a Python thread on a shared machine
    return DriverSettings(port=bus.path, options={"calibration": str(cal), "gripper": "joint_4",
                                                  "timeout": "2", **extra})


def test_a_trajectory_reaches_its_goal_in_ticks(desc, cal_file, planned):
    bus = SimBus(at_zero(), homing=HOMING)
    try:
        with FeetechArm.connect(desc, settings(bus, cal_file)) as arm:
            assert all(s.torque for s in bus.servos.values())  # torque on at open
            # the first goal each servo got is where it stood: torque on moved nothing
            assert {i: s.goals[0] for i, s in bus.servos.items()} == at_zero()
            report = Executor.for_description(arm, desc, options=ExecuteOptions(
                rate=100.0)).execute(planned)
    finally:
        bus.close()
    assert report.outcome == "completed"
    assert bus.bad_checksums == 0
    end = planned.positions[-1]
    for j, q in zip(("joint_1", "joint_2", "joint_3", "joint_4"), end):
        s = bus.servos[CALIBRATION[j]["id"]]
        assert abs(s.goals[-1] - expected_ticks(j, float(q))) <= 0.5 + 1e-9, j
        assert s.present == s.goals[-1]
    # the report's measured positions are the servos' ticks read back: within a tick
    tick = 2 * math.pi / 4095
    assert np.max(np.abs(report.measured[-1] - end)) <= tick
    # one SYNC_WRITE per tick after the opening hold, one SYNC_READ per state read
    sync_writes = [p for p in bus.packets if p[1] == 0x83]
    assert len(sync_writes) == 1 + report.ticks
    assert any(sid == 4 and ins == 0x01 for sid, ins, _ in bus.packets)  # pinged
    # the gripper moved on the 0-100 scale: -0.8 of [-1.5708, 0] is 49 %, turned round
    assert bus.servos[4].goals[-1] == round(2000 + 0.50930 * 1000)


def test_the_command_line_runs_a_trajectory_through_the_driver(tmp_path, cal_file, planned):
    traj = tmp_path / "traj.json"
    traj.write_text(json.dumps({"trajectory": {
        "joint_names": list(planned.joint_names),
        "points": [{"time_from_start": float(t), "positions": list(map(float, q))}
                   for t, q in zip(planned.times, planned.positions)]}}))
    out = tmp_path / "report.json"
    bus = SimBus(at_zero(), homing=HOMING)
    try:
        code = main(["execute", str(traj), "--driver", "feetech", "--port", bus.path,
                     "--driver-option", f"calibration={cal_file}", "--driver-option",
                     "gripper=joint_4", "--driver-option", "timeout=2", "--no-publish",
                     "--report", str(out)])
    finally:
        bus.close()
    assert code == 0
    r = json.loads(out.read_text())
    assert r["outcome"] == "completed"
    assert np.allclose(r["final_positions"], planned.positions[-1], atol=2 * math.pi / 4095)


def test_unplugged(desc, cal_file, planned, tmp_path):
    with pytest.raises(PortNotFound) as e:
        FeetechArm.connect(desc, DriverSettings(port=str(tmp_path / "ttyACM9"),
                                                options={"calibration": str(cal_file)}))
    assert e.value.code == "PORT_NOT_FOUND" and "ttyACM9" in e.value.message

    bus = SimBus(at_zero(), homing=HOMING)

    def pull(tick):
        if tick.index == 20:
            bus.unplug()
    with FeetechArm.connect(desc, settings(bus, cal_file)) as arm:
        ex = Executor.for_description(arm, desc, options=ExecuteOptions(rate=100.0),
                                      on_tick=pull)
        with pytest.raises(PortError) as e:
            ex.execute(planned)
    assert e.value.code == "PORT_ERROR"
    assert e.value.details["tick"] == 21  # the first tick after the pull
    # each servo holds the last goal it took (tick 20's): nothing could reach it after
    held = e.value.details["last_commanded"]
    assert set(held) == {"joint_1", "joint_2", "joint_3", "joint_4"}


def test_a_servo_that_does_not_answer(desc, cal_file, planned):
    bus = SimBus(at_zero(), homing=HOMING)
    bus.servos[3].silent = True
    try:
        with pytest.raises(ServoNoResponse) as e:
            FeetechArm.connect(desc, settings(bus, cal_file, timeout="0.2"))
    finally:
        bus.close()
    assert e.value.code == "SERVO_NO_RESPONSE" and e.value.details["servo"] == 3
    assert not any(s.torque for s in bus.servos.values())  # nothing was switched on

    bus = SimBus(at_zero(), homing=HOMING)

    def mute(tick):
        if tick.index == 30:
            bus.servos[3].silent = True
    try:
        with FeetechArm.connect(desc, settings(bus, cal_file, timeout="0.2")) as arm:
            ex = Executor.for_description(arm, desc, options=ExecuteOptions(rate=100.0),
                                          on_tick=mute)
            with pytest.raises(ServoNoResponse) as e:
                ex.execute(planned)
    finally:
        bus.close()
    assert e.value.details["servo"] == 3 and e.value.details["tick"] == 31  # the next read
    # stopped: the servos that listen got where they were read as their goal, torque on
    for i in (1, 2, 4):
        s = bus.servos[i]
        assert s.goals[-1] == s.present and s.torque
        assert s.goals[-1] != s.goals[-2] or s.goals[-2] == s.present


def test_a_position_read_back_far_from_the_command(desc, cal_file, planned):
    bus = SimBus(at_zero(), homing=HOMING)

    def block(tick):
        if tick.index == 5:
            bus.servos[1].stuck = True  # joint_1 blocked: its present stays put
    try:
        with FeetechArm.connect(desc, settings(bus, cal_file, max_error="0.05")) as arm:
            ex = Executor.for_description(arm, desc, options=ExecuteOptions(rate=100.0),
                                          on_tick=block)
            with pytest.raises(TrackingError) as e:
                ex.execute(planned)
            d = e.value.details
    finally:
        bus.close()
    assert e.value.code == "TRACKING_ERROR" and d["joint"] == "joint_1" and d["servo"] == 1
    assert abs(d["read"] - d["commanded"]) > 0.05
    assert d["tick"] < 100  # mid-motion, not at the end (150 ticks)
    # the arm stopped: every servo's last goal is where it stands, torque on
    for s in bus.servos.values():
        assert s.goals[-1] == s.present and s.torque, s.id
    assert bus.servos[1].goals[-2] != bus.servos[1].present  # it was told to go on before


def test_a_gripper_closing_on_an_object_is_not_a_fault(desc, cal_file, planned):
    """The gripper stops short of its command on what it grips: not a tracking error."""
    bus = SimBus(at_zero(), homing=HOMING)

    def grip(tick):
        if tick.index == 60:
            bus.servos[4].stuck = True  # the jaws met the object
    try:
        with FeetechArm.connect(desc, settings(bus, cal_file, max_error="0.05")) as arm:
            report = Executor.for_description(arm, desc, options=ExecuteOptions(
                rate=100.0), on_tick=grip).execute(planned)
    finally:
        bus.close()
    assert report.outcome == "completed"
    s = bus.servos[4]
    assert abs(s.goals[-1] - s.present) > 100  # far from its command, and no error
    assert bus.servos[1].present == bus.servos[1].goals[-1]


def test_a_servo_that_reports_overload(desc, cal_file, planned):
    bus = SimBus(at_zero(), homing=HOMING)

    def overload(tick):
        if tick.index == 10:
            bus.servos[2].error = 32
    try:
        with FeetechArm.connect(desc, settings(bus, cal_file)) as arm:
            ex = Executor.for_description(arm, desc, options=ExecuteOptions(rate=100.0),
                                          on_tick=overload)
            with pytest.raises(ServoFault) as e:
                ex.execute(planned)
    finally:
        bus.close()
    assert e.value.code == "SERVO_FAULT" and e.value.details["servo"] == 2
    assert e.value.details["errors"] == ["overload"] and "overload" in e.value.message
    for s in bus.servos.values():  # held where it stands
        assert s.goals[-1] == s.present and s.torque, s.id


def test_a_calibration_that_is_not_the_servos(desc, cal_file):
    bus = SimBus(at_zero(), homing={**HOMING, 2: 99})
    try:
        with pytest.raises(CalibrationMismatch) as e:
            FeetechArm.connect(desc, settings(bus, cal_file))
    finally:
        bus.close()
    assert e.value.code == "CALIBRATION_MISMATCH"
    assert e.value.details["servo"] == 2 and e.value.details["servo_offset"] == 99


@pytest.mark.parametrize(("body", "field"), [
    ({"joint_1": {"id": 1}}, "joint_1"),
    ({"joint_1": {**CALIBRATION["joint_1"], "range_min": 4000}}, "joint_1.range_min"),
    ({**CALIBRATION, "joint_3": {**CALIBRATION["joint_3"], "id": 1}}, "id"),
    ({"shoulder_pan": CALIBRATION["joint_1"]}, "motor.joint_1"),
])
def test_a_bad_calibration_file_names_its_field(desc, tmp_path, body, field):
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(body))
    with pytest.raises(InvalidCalibration) as e:
        FeetechArm.connect(desc, DriverSettings(port="/dev/null",
                                                options={"calibration": str(p)}))
    assert e.value.code == "INVALID_CALIBRATION" and e.value.details["field"] == field


def test_a_bus_for_a_calibration_file_rests_at_zero(desc, cal_file):
    bus = SimBus.for_calibration(CALIBRATION)
    try:
        with FeetechArm.connect(desc, settings(bus, cal_file)) as arm:
            q = arm.state().actuated(arm.joint_names)
    finally:
        bus.close()
    assert np.allclose(q[:3], 0.0, atol=2 * math.pi / 4095)
    assert abs(q[3] - (GRIPPER_LOWER + GRIPPER_UPPER) / 2) < 1e-3  # the gripper half open


def test_motor_names_map_joints(desc, tmp_path):
    """A file named as LeRobot names the SO-101's motors, mapped with motor.JOINT."""
    names = dict(zip(("joint_1", "joint_2", "joint_3", "joint_4"),
                     ("shoulder_pan", "shoulder_lift", "elbow_flex", "gripper")))
    p = tmp_path / "so.json"
    p.write_text(json.dumps({names[j]: c for j, c in CALIBRATION.items()}))
    bus = SimBus(at_zero(), homing=HOMING)
    try:
        with FeetechArm.connect(desc, settings(bus, p, **{
                f"motor.{j}": m for j, m in names.items()})) as arm:
            st = arm.state()
    finally:
        bus.close()
    assert np.allclose(st.actuated(arm.joint_names), 0.0, atol=2 * math.pi / 4095)
    assert [j.servo for j in arm.joints] == [1, 2, 3, 4]


def test_the_simulated_bus_answers_feetechs_own_sdk(monkeypatch):
    """The simulated bus is checked against Feetech's scservo_sdk (feetech-servo-sdk,
    what LeRobot drives these servos with): its PING, READ, WRITE, SYNC_WRITE and
    SYNC_READ get what the manual says, so the driver's tests above meet a faithful bus."""
    import scservo_sdk as scs  # feetech-servo-sdk, in the test extra
    import scservo_sdk.port_handler
    # the SDK waits 2 x LATENCY_TIMER + 2 ms of wall clock (34 ms) for an answer: the
    # simulated bus is a Python thread on a shared machine, so give it ~2 s
    monkeypatch.setattr(scservo_sdk.port_handler, "LATENCY_TIMER", 1000)
    bus = SimBus({1: 2048, 2: 1000}, homing={1: -1470})
    port = scs.PortHandler(bus.path)
    try:
        assert port.openPort()
        ph = scs.PacketHandler(0)  # STS: little-endian words
        model, res, err = ph.ping(port, 1)
        assert (model, res, err) == (777, scs.COMM_SUCCESS, 0)
        raw, res, _ = ph.read2ByteTxRx(port, 1, 31)
        assert res == scs.COMM_SUCCESS and raw == 1470 | (1 << 11)  # sign bit 11
        assert ph.write1ByteTxRx(port, 1, 40, 1) == (scs.COMM_SUCCESS, 0)  # torque on
        assert ph.write1ByteTxRx(port, 2, 40, 1) == (scs.COMM_SUCCESS, 0)
        sw = scs.GroupSyncWrite(port, ph, 42, 2)
        sw.addParam(1, [0x10, 0x09])  # 2320
        sw.addParam(2, [0xE8, 0x04])  # 1256
        assert sw.txPacket() == scs.COMM_SUCCESS
        sr = scs.GroupSyncRead(port, ph, 56, 2)
        sr.addParam(1)
        sr.addParam(2)
        assert sr.txRxPacket() == scs.COMM_SUCCESS
        assert sr.getData(1, 56, 2) == 2320 and sr.getData(2, 56, 2) == 1256
        _, res, _ = ph.ping(port, 9)  # no servo 9 on this bus
        assert res == scs.COMM_RX_TIMEOUT
    finally:
        port.closePort()
        bus.close()
    assert bus.bad_checksums == 0
    assert bus.servos[1].goals == [2320] and bus.servos[2].goals == [1256]


def test_serve_opens_the_driver_its_options_name(desc, cal_file):
    """`serve --driver feetech --port ... --driver-option ...`: the robot the service's
    <prefix>/execute drives (its RobotSpec) opens the bus as execute does."""
    from arduinobot.cli.commands.execute import robot_spec
    from arduinobot.cli.main import build_parser
    bus = SimBus(at_zero(), homing=HOMING)
    try:
        ns = build_parser().parse_args([
            "serve", "--driver", "feetech", "--port", bus.path, "--rate", "50",
            "--driver-option", f"calibration={cal_file}", "--driver-option", "timeout=2",
            "--driver-option", "gripper=joint_4"])
        spec = robot_spec(ns)
        assert (spec.kind, spec.driver, spec.port, spec.rate) == ("driver", "feetech",
                                                                   bus.path, 50.0)
        with spec.open(desc) as arm:
            assert isinstance(arm, FeetechArm) and arm.period == 1 / 50
            assert np.allclose(arm.state().actuated(arm.joint_names), 0.0,
                               atol=2 * math.pi / 4095)
    finally:
        bus.close()


def test_torque_stays_on_at_close_unless_released(desc, cal_file):
    for on_close, torque in (("hold", True), ("release", False)):
        bus = SimBus(at_zero(), homing=HOMING)
        try:
            with FeetechArm.connect(desc, settings(bus, cal_file, on_close=on_close)):
                assert all(s.torque for s in bus.servos.values())
            assert all(s.torque is torque for s in bus.servos.values()), on_close
        finally:
            bus.close()
    bus = SimBus(at_zero(), homing=HOMING)
    try:
        with pytest.raises(RobotError) as e:
            FeetechArm.connect(desc, settings(bus, cal_file, on_close="drop"))
        assert e.value.details["field"] == "driver_option.on_close"
        with pytest.raises(RobotError) as e:
            FeetechArm.connect(desc, settings(bus, cal_file, speed="9"))
        assert e.value.details["field"] == "driver_option.speed"
    finally:
        bus.close()


@pytest.mark.slow
def test_serve_drives_the_bus_for_a_remote_execute(cal_file, planned):
    """`serve --driver feetech`: a client's execute moves the simulated bus to the goal."""
    from arduinobot import PlannerClient
    from tests.helpers.serve import start_server
    bus = SimBus(at_zero(), homing=HOMING)
    srv = start_server(["--workers", "1", "--driver", "feetech", "--port", bus.path,
                        "--driver-option", f"calibration={cal_file}",
                        "--driver-option", "gripper=joint_4", "--driver-option", "timeout=2"],
                       timeout=300)
    try:
        assert "feetech" in "\n".join(srv.stderr_lines)  # the ready log names the driver
        with PlannerClient(srv.endpoint, timeout=60) as c:
            done = c.execute({"joint_names": list(planned.joint_names), "points": [
                {"time_from_start": float(t), "positions": list(map(float, q))}
                for t, q in zip(planned.times, planned.positions)]})
    finally:
        srv.stop()
        bus.close()
    assert done.report["outcome"] == "completed"
    for j, q in zip(("joint_1", "joint_2", "joint_3", "joint_4"), planned.positions[-1]):
        s = bus.servos[CALIBRATION[j]["id"]]
        assert abs(s.goals[-1] - expected_ticks(j, float(q))) <= 0.5 + 1e-9, j
        assert s.present == s.goals[-1]


@pytest.mark.slow
def test_a_task_runs_on_the_bus(cal_file, tmp_path):
    """`task 1 --driver feetech`: the course's pick, planned from the servos' own state
    and played on the simulated bus to its last step's goal (slow: real time)."""
    bus = SimBus.for_calibration(CALIBRATION)
    out = tmp_path / "task.json"
    try:
        code = main(["task", "1", "--driver", "feetech", "--port", bus.path,
                     "--driver-option", f"calibration={cal_file}", "--driver-option",
                     "gripper=joint_4", "--driver-option", "timeout=2", "--report", str(out)])
    finally:
        bus.close()
    assert code == 0
    r = json.loads(out.read_text())["execution"]
    assert r["outcome"] == "completed"
    assert bus.bad_checksums == 0
    for j, q in zip(r["joint_names"], r["final_positions"]):
        s = bus.servos[CALIBRATION[j]["id"]]
        assert s.present == s.goals[-1]
        assert abs(s.goals[-1] - expected_ticks(j, q)) <= 1.5, j  # read back within a tick
