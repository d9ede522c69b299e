"""Plan requests and replies on the wire (service/plan_io.py): the sample cap."""

from __future__ import annotations

import json

import pytest

from planner.errors import InvalidRequest
from planner.timing.trajectory import check_sample_count
from service import caps, wire
from service.plan_io import plan_request, plan_response

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
    from description import load_description
    from planner.planning.pipeline import MotionPlanner
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
