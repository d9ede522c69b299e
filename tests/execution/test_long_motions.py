"""Issue 38, item 1, typed as a user of the course's workspace did: its MoveIt config
scales speeds to 0.1, so a pick and place lasts ~18 s, and `task FILE --remote` and
`execute FILE --remote` of such a motion must run, not be refused after planning by the
service's own request cap."""

from __future__ import annotations

import json

import numpy as np
import pytest

from arduinobot.contract.packed import PackedError, pack, unpack
from tests.helpers.cli import run_cli
from tests.helpers.pick_place import pick_and_place
from tests.helpers.serve import start_server


@pytest.fixture(scope="module")
def slow_course_service(course_ws):
    """`arduinobot serve` on the course's workspace as the Setup Assistant left it: its
    joint_limits.yaml scales speeds to 0.1."""
    srv = start_server(["--workers", "1", str(course_ws.xacro), "--package-dir",
                        str(course_ws.src), "--moveit-config", str(course_ws.moveit_pkg)],
                       timeout=240)
    yield srv
    srv.stop()


def test_packed_samples_round_trip_bit_for_bit():
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 2.0, 7)
    q, qd, qdd = (rng.normal(size=(7, 4)) for _ in range(3))
    times, q2, qd2, qdd2, tau = unpack(pack(t, q, qd, qdd), 4,
                                       optional=frozenset({"effort"}))
    assert tau is None
    for a, b in ((t, times), (q, q2), (qd, qd2), (qdd, qdd2)):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("change, field", [
    ({"samples": -1}, "trajectory.packed.samples"),
    ({"positions": "not base64!"}, "trajectory.packed.positions"),
    ({"velocities": "AAAA"}, "trajectory.packed.velocities"),
])
def test_a_bad_packed_array_is_named(change, field):
    body = {**pack(np.zeros(2), np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)),
                   np.zeros((2, 3))), **change}
    with pytest.raises(PackedError) as e:
        unpack(body, 3)
    assert e.value.field == field


def test_execute_reads_a_packed_trajectory_as_its_points():
    from arduinobot.execution.segments import InvalidTrajectory, SampledTrajectory
    t = np.linspace(0.0, 1.0, 11)
    q = np.stack([np.sin(t), np.cos(t)], axis=1)
    names = ["joint_1", "joint_2"]
    packed = SampledTrajectory.from_json({"joint_names": names, "packed": pack(t, q)})
    points = SampledTrajectory.from_json({"joint_names": names, "points": [
        {"positions": row.tolist(), "time_from_start": float(ti)} for row, ti in zip(q, t)]})
    assert np.array_equal(packed.positions, points.positions)
    assert np.array_equal(packed.velocities, points.velocities)
    with pytest.raises(InvalidTrajectory, match="trajectory.packed.time_from_start"):
        SampledTrajectory.from_json({"joint_names": names, "packed": pack(t[::-1], q)})


def test_an_execute_request_takes_any_trajectory_a_plan_reply_holds():
    from arduinobot.contract import caps, wire
    # the most samples a plan reply holds, as JSON points, for a 7-joint arm
    row = {"positions": [-1.2345678901234567] * 7, "velocities": [1.2345678901234567] * 7,
           "accelerations": [12.345678901234567] * 7, "effort": [1.2345678901234567] * 7,
           "time_from_start": 123.45678901234567}
    size = caps.MAX_SAMPLES * len(json.dumps(row, separators=(",", ":")))
    assert size < caps.MAX_EXECUTE_PAYLOAD
    assert wire.payload_cap("execute") == caps.MAX_EXECUTE_PAYLOAD
    assert wire.payload_cap("plan") == caps.MAX_PAYLOAD < caps.MAX_EXECUTE_PAYLOAD


@pytest.mark.slow
def test_a_long_task_file_runs_on_the_services_robot(slow_course_service, tmp_path):
    # the pick and place slower than the course's 0.1, as a user slowing a demo down
    task = {**pick_and_place(), "velocity_scaling": 0.03, "acceleration_scaling": 0.03}
    f = tmp_path / "pick_place.json"
    f.write_text(json.dumps(task))
    out = tmp_path / "report.json"
    run = run_cli("task", str(f), "--remote", "--connect", slow_course_service.endpoint,
               "--report", str(out))
    assert run.returncode == 0, run.stderr
    r = json.loads(out.read_text())
    # a motion of well over the ~10 s whose points once fit the cap
    assert r["planned"]["duration"] > 15.0, r["planned"]["duration"]
    assert r["execution"]["outcome"] == "completed", r["execution"]


@pytest.mark.slow
def test_a_long_plan_file_executes_on_the_services_robot(slow_course_service, tmp_path):
    traj = tmp_path / "traj.json"
    ep = ["--connect", slow_course_service.endpoint]
    # across the workspace, slower than the course's 0.1
    plan = run_cli("plan", "--start", "1.5,-0.6,0.6", "--goal", "-1.5,0.6,-0.6",
                "--velocity-scaling", "0.02", "--acceleration-scaling", "0.02",
                "--seed", "2", "--json", str(traj), *ep)
    assert plan.returncode == 0, plan.stderr
    body = json.loads(traj.read_text())
    assert body["duration"] > 15.0, body["duration"]
    # the file as plan --json writes it: JSON points, well over the 256 KiB request cap
    assert traj.stat().st_size > 256 * 1024
    run = run_cli("execute", str(traj), "--remote", "--move-to-start", *ep)
    assert run.returncode == 0, run.stderr
    assert "completed" in run.stdout, run.stdout
