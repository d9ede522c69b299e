"""The published JSON Schemas and the strict wire parsing (no server needed)."""

from __future__ import annotations

import json

import jsonschema
import pytest

from planner.errors import InvalidRequest, JointLimitViolation
from service import wire
from service.requests import joint_values


def test_every_schema_is_a_valid_draft_2020_12_schema():
    for name in wire.SCHEMA_NAMES:
        jsonschema.Draft202012Validator.check_schema(wire.schema(name))
    assert set(wire.all_schemas()) == set(wire.SCHEMA_NAMES)


def test_minimal_and_full_plan_requests_pass():
    assert wire.decode("plan", b'{"goal": {"named": "home"}}') == {"goal": {"named": "home"}}
    full = {"start": {"joint_1": 0.1}, "goal": {"position": [0, 1, 1.2]}, "group": "all",
            "obstacles": [{"id": "table", "shape": "box", "size": [1, 1, 0.1],
                           "xyz": [0, 1, 0.5], "rpy": [0, 0, 0.3]},
                          {"id": "ball", "shape": "sphere", "radius": 0.1},
                          {"id": "post", "shape": "cylinder", "radius": 0.1, "length": 1}],
            "planner": "RRTConnect", "planning_time": 2.5, "velocity_scaling": 0.5,
            "acceleration_scaling": 0.5, "profile": "time_optimal", "sample_rate": 250,
            "seed": 7}
    assert wire.decode("plan", json.dumps(full)) == full


@pytest.mark.parametrize("payload, field", [
    ('{"goal": {"named": "home"}, "speed": 1}', "speed"),
    ('{"goal": {"joints": {"joint_1": "fast"}}}', "goal.joints.joint_1"),
    ('{"goal": {"position": [1, 2, 1e999]}}', "goal.position[2]"),
    ('{"goal": {"named": "home"}, "sample_rate": 1001}', "sample_rate"),
    ('{"goal": {"named": "home"}, "sample_rate": 0.5}', "sample_rate"),
    ('{"goal": {"named": "home"}, "planning_time": 61}', "planning_time"),
    ('{"goal": {"named": "home"}, "planning_time": 0}', "planning_time"),
    ('{"goal": {"named": "home"}, "velocity_scaling": 1.5}', "velocity_scaling"),
    ('{"goal": {"named": "home"}, "seed": -1}', "seed"),
    ('{"goal": {"named": "home"}, "seed": 1.5}', "seed"),
    ('{"goal": {"named": "home"}, "obstacles": [{"id": "t", "shape": "box", "size": [1, 1]}]}',
     "obstacles[0].size"),
    ('{"goal": {"named": "home"}, "obstacles": [{"id": "t", "shape": "box", "size": [1, 1, 0]}]}',
     "obstacles[0].size[2]"),
    (('{"goal": {"named": "home"}, "obstacles": [{"id": "t", "shape": "mesh", '
      '"mesh_path": "/etc/passwd"}]}'),
     "obstacles[0].mesh_path"),
    ('{"goal": {"named": "home"}, "group": ""}', "group"),
    ('{"start": {"joint_1": 0}}', "(root)"),
])
def test_refusals_name_the_field(payload, field):
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", payload)
    assert e.value.details["field"] == field


@pytest.mark.parametrize("payload", [b"NaN", b'{"goal": {"position": [NaN, 0, 0]}}',
                                     b'{"goal": {"position": [Infinity, 0, 0]}}',
                                     b'{"goal": {"position": [-Infinity, 0, 0]}}'])
def test_nan_and_infinity_tokens_are_refused(payload):
    with pytest.raises(InvalidRequest, match="finite"):
        wire.decode("plan", payload)


def test_malformed_json_reports_line_and_column():
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", b'{"goal": \n {"named": }')
    assert e.value.details["line"] == 2


def test_payload_over_the_cap_is_refused_before_parsing():
    big = b'{"goal": {"named": "home"}, "planner": "' + b"x" * wire.MAX_PAYLOAD + b'"}'
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", big)
    assert e.value.details["limit"] == wire.MAX_PAYLOAD


def test_too_many_obstacles_are_refused():
    obs = [{"id": f"o{i}", "shape": "sphere", "radius": 0.1} for i in range(257)]
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", json.dumps({"goal": {"named": "home"}, "obstacles": obs}))
    assert e.value.details["field"] == "obstacles"


def test_encode_refuses_non_finite_and_converts_numpy():
    import numpy as np
    assert json.loads(wire.encode({"a": np.float64(1.5), "b": np.arange(2)})) == \
        {"a": 1.5, "b": [0, 1]}
    with pytest.raises(ValueError):
        wire.encode({"a": float("nan")})


def test_joint_values_check_names_mimics_and_limits(description):
    assert joint_values(description, {"joint_2": 0.5}, field="start") == \
        {"joint_1": 0.0, "joint_2": 0.5, "joint_3": 0.0, "joint_4": 0.0}
    with pytest.raises(InvalidRequest) as e:
        joint_values(description, {"joint_5": 0.1}, field="start")
    assert e.value.details["leader"] == "joint_4" and "joint_4" in e.value.message
    with pytest.raises(InvalidRequest) as e:
        joint_values(description, {"elbow": 0.1}, field="goal.joints")
    assert e.value.details["field"] == "goal.joints.elbow"
    with pytest.raises(JointLimitViolation) as e:
        joint_values(description, {"joint_4": 0.5}, field="start")
    assert e.value.details["upper"] == pytest.approx(0.0)


@pytest.fixture(scope="module")
def description():
    from description import load_description
    return load_description()
