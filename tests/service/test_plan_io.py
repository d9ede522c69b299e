"""Plan requests and replies on the wire (src/arduinobot/service/plan/plan_io.py): the sample cap, the reply
built from the sample arrays, its packed form."""

from __future__ import annotations

import base64
import json
from dataclasses import replace

import numpy as np
import pytest

from arduinobot.contract import caps, wire
from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.planner.timing.trajectory import check_sample_count
from arduinobot.service.plan.plan_io import plan_reply, plan_request, plan_response

#: the cap plan_response's guard on its reply passes
CAP = {"limit": caps.MAX_SAMPLES, "cap": "MAX_SAMPLES"}


def test_the_sample_cap_names_the_field_the_cap_and_a_rate_that_fits():
    check_sample_count(caps.MAX_SAMPLES, duration=20.0, sample_rate=1000.0, **CAP)
    with pytest.raises(InvalidRequest) as e:
        check_sample_count(caps.MAX_SAMPLES + 1, duration=20.0, sample_rate=1000.0, **CAP)
    d = e.value.details
    assert d["field"] == "sample_rate" and d["limit"] == caps.MAX_SAMPLES
    assert str(caps.MAX_SAMPLES) in e.value.message
    assert 1.0 <= d["max_sample_rate"] and 20.0 * d["max_sample_rate"] + 2 <= caps.MAX_SAMPLES


def test_no_rate_fits_a_motion_longer_than_the_cap_in_seconds():
    with pytest.raises(InvalidRequest) as e:
        check_sample_count(caps.MAX_SAMPLES * 2, duration=caps.MAX_SAMPLES * 2.0, sample_rate=1.0,
                           **CAP)
    assert e.value.details["max_sample_rate"] == 0.0 and "scalings" in e.value.message


@pytest.fixture(scope="module")
def planner():
    from arduinobot.description import load_description
    from arduinobot.planner.planning.pipeline import MotionPlanner
    d = load_description()
    return d, MotionPlanner(d)


def _sweep(rate: float) -> dict:
    # joint_1 across its whole range at the slowest scaling: ~32 s
    return {"start": {"joint_1": -1.55}, "goal": {"joints": {"joint_1": 1.55}}, "seed": 1,
            "velocity_scaling": caps.MIN_SCALING, "acceleration_scaling": caps.MIN_SCALING,
            "sample_rate": rate}


def test_a_plan_over_the_sample_cap_is_refused_before_sampling_and_the_rate_it_names_fits(
        planner):
    d, mp = planner
    req = plan_request(d, wire.decode("plan", json.dumps(_sweep(1000))))
    assert req.max_samples == caps.MAX_SAMPLES
    with pytest.raises(InvalidRequest) as e:
        mp.solve(req)  # refused in the planner, before ~32,000 samples are made
    fits = e.value.details["max_sample_rate"]
    assert e.value.details["field"] == "sample_rate" and 1 <= fits < 1000
    assert e.value.details["samples"] > caps.MAX_SAMPLES  # else this test proves nothing
    body = plan_response(mp.solve(plan_request(d, wire.decode("plan",
                                                              json.dumps(_sweep(fits))))))
    assert caps.MAX_SAMPLES // 2 < len(body["trajectory"]["points"]) <= caps.MAX_SAMPLES
    assert len(wire.encode(body, finite=True)) < 10_000_000


def test_an_integral_float_seed_is_an_int(planner):
    d, _ = planner
    req = plan_request(d, wire.decode("plan", b'{"goal": {"named": "home"}, "seed": 7.0}'))
    assert req.seed == 7 and isinstance(req.seed, int)


def _result(planner, rate: float = 100.0):
    d, mp = planner
    return mp.solve(plan_request(d, wire.decode("plan", json.dumps(
        {"start": {"joint_1": -1.2, "joint_2": 0.5}, "goal": {"named": "reach_left"},
         "seed": 3, "sample_rate": rate}))))


def test_the_encoded_reply_is_the_dict_reply_byte_for_byte(planner):
    """plan_reply (what a worker sends, built from the sample arrays) writes exactly what
    encoding plan_response's dict writes: same keys, order and numbers."""
    for rate in (100.0, 7.0):
        result = _result(planner, rate)
        assert len(result.trajectory.times) > 2  # several points, so rows are cut apart
        encoded = plan_reply(result, "r-1")
        assert encoded == wire.encode(
            {**plan_response(result), "scene_revision": 0, "request_id": "r-1"}, finite=True)
        body = json.loads(encoded)
        wire.validator("plan_response").validate(body)
        assert body["trajectory"]["points"][-1]["positions"] == \
            result.trajectory.positions[-1].tolist()


def test_the_encoded_reply_of_one_sample_and_a_non_finite_one(planner):
    result = _result(planner)
    traj = result.trajectory
    one = replace(result, trajectory=replace(
        traj, times=traj.times[:1], positions=traj.positions[:1],
        velocities=traj.velocities[:1], accelerations=traj.accelerations[:1],
        efforts=traj.efforts[:1]))
    assert plan_reply(one, "r") == wire.encode(
        {**plan_response(one), "scene_revision": 0, "request_id": "r"}, finite=True)
    assert len(json.loads(plan_reply(one, "r"))["trajectory"]["points"]) == 1
    bad = traj.velocities.copy()
    bad[1, 0] = float("nan")
    with pytest.raises(PlanningError, match="non-finite velocities"):
        plan_reply(replace(result, trajectory=replace(traj, velocities=bad)), "r")


def test_a_packed_reply_holds_the_sample_arrays_bit_for_bit(planner):
    """trajectory_format "packed": the worker's bytes are the dict reply's, schema-valid,
    and each array decodes to the planner's own float64 values (little-endian,
    row-major); "points" stays the default."""
    result = _result(planner)
    traj = result.trajectory
    encoded = plan_reply(result, "r-2", trajectory_format="packed")
    assert encoded == wire.encode({**plan_response(result, trajectory_format="packed"),
                                   "scene_revision": 0, "request_id": "r-2"}, finite=True)
    body = json.loads(encoded)
    wire.validator("plan_response").validate(body)
    packed = body["trajectory"]["packed"]
    assert "points" not in body["trajectory"] and packed["samples"] == len(traj.times)
    m, n = traj.positions.shape
    for key, want in (("time_from_start", traj.times), ("positions", traj.positions),
                      ("velocities", traj.velocities), ("accelerations", traj.accelerations),
                      ("effort", traj.efforts)):
        got = np.frombuffer(base64.b64decode(packed[key]), "<f8")
        assert np.array_equal(got.reshape(want.shape), want), key
    assert len(encoded) < len(plan_reply(result, "r-2")) / 1.5  # what packing is for
    assert "points" in json.loads(plan_reply(result, "r-2"))["trajectory"]


def test_a_request_asks_for_a_packed_trajectory_by_name():
    assert wire.decode("plan", b'{"goal": {"named": "home"}, "trajectory_format": "packed"}'
                       )["trajectory_format"] == "packed"
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", b'{"goal": {"named": "home"}, "trajectory_format": "binary"}')
    assert e.value.details["field"] == "trajectory_format"
