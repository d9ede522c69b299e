"""The SO-101's pick and place (its shipped task 2) through the Feetech driver on the
simulated bus (issue 38: "the Feetech driver moves a simulated bus through the same
task"): ``arduinobot task 2 so101_new_calib.urdf --driver feetech`` with a LeRobot
calibration file, every goal position the bus saw decoded by tests/helpers/feetech_bus.py
(written from Feetech's manual, not from the driver)."""

from __future__ import annotations

import json

import numpy as np

from arduinobot.cli.main import main
from tests.helpers.feetech_bus import SimBus
from tests.helpers.so101 import (
    ARM_JOINTS,
    CALIBRATION,
    GRIPPER_JOINT,
    calibration_ticks,
    make_so101,
)

JOINTS = (*ARM_JOINTS, GRIPPER_JOINT)
SYNC_WRITE = 0x83
GOAL_POSITION = 42  # the STS memory table's Goal_Position


def _goal_writes(bus: SimBus) -> list[dict[int, int]]:
    """Every SYNC_WRITE of Goal_Position the bus saw, as {servo id: ticks}, in order."""
    out = []
    for _, ins, p in bus.packets:
        if ins == SYNC_WRITE and p[0] == GOAL_POSITION:
            n = p[1]
            out.append({p[k]: p[k + 1] | (p[k + 2] << 8) for k in range(2, len(p), n + 1)})
    return out


def test_the_so101_pick_and_place_moves_the_feetech_bus(tmp_path):
    urdf = make_so101(tmp_path)
    cal = tmp_path / "so101_follower.json"
    cal.write_text(json.dumps(CALIBRATION))
    out = tmp_path / "report.json"
    bus = SimBus.for_calibration(CALIBRATION)
    try:
        code = main(["task", "2", str(urdf), "--driver", "feetech", "--port", bus.path,
                     "--driver-option", f"calibration={cal}",
                     "--driver-option", "timeout=2",  # a Python thread on a shared machine
                     "--report", str(out)])
    finally:
        bus.close()
    assert code == 0
    assert bus.bad_checksums == 0
    rep = json.loads(out.read_text())
    ex = rep["execution"]
    assert ex["outcome"] == "completed", ex
    planned = rep["planned"]
    assert all(s["certified"] and s["verified"] for s in planned["steps"]
               if s["kind"] not in ("attach", "detach"))
    writes = _goal_writes(bus)
    ids = {CALIBRATION[j]["id"] for j in JOINTS}
    assert all(set(w) == ids for w in writes)  # every servo in every tick's write
    assert len(writes) == 1 + ex["ticks"]  # the opening hold, then one a tick
    # the task started where the servos stood (the middle of each range: 0 rad, the
    # gripper at half its scale), and the bus saw every step's planned end, in order
    first = planned["steps"][0]["start"]
    for j in JOINTS:
        sid = CALIBRATION[j]["id"]
        assert abs(writes[0][sid] - calibration_ticks(j, first[j])) <= 1, j
    seen = np.array([[w[CALIBRATION[j]["id"]] for j in JOINTS] for w in writes], float)
    k = 0
    for s in planned["steps"]:
        want = np.array([calibration_ticks(j, s["end"][j]) for j in JOINTS])
        hits = np.flatnonzero(np.all(np.abs(seen[k:] - want) <= 1.0, axis=1))
        assert hits.size, (s["index"], s["kind"], want.round(1))
        k += int(hits[0])
    # the pan turned 0.7 rad to the place and back nowhere else; the jaws opened to 1.5
    # rad and closed to 0, on LeRobot's 0-100 scale
    pan = seen[:, 0]
    assert abs(pan.max() - calibration_ticks("shoulder_pan", 0.7)) <= 1
    jaw = seen[:, -1]
    assert abs(jaw.max() - calibration_ticks(GRIPPER_JOINT, 1.5)) <= 1
    assert abs(jaw[1:].min() - calibration_ticks(GRIPPER_JOINT, 0.0)) <= 1
    # what the report measured is the servos' ticks read back: the end of the plan
    end = planned["steps"][-1]["end"]
    final = dict(zip(ex["joint_names"], ex["final_positions"]))
    tick = 2 * np.pi / 4095
    for j in ARM_JOINTS:
        assert abs(final[j] - end[j]) <= tick, j
