"""The published JSON Schemas and the strict wire parsing (no server needed)."""

from __future__ import annotations

import json

import jsonschema
import pytest

from arduinobot.contract import caps, wire
from arduinobot.contract.errors import InvalidRequest, JointLimitViolation
from arduinobot.planner.checks import joint_values


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
     "obstacles[0].shape"),
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


def test_joint_values_check_names_mimics_and_limits(desc):
    assert joint_values(desc, {"joint_2": 0.5}, field="start") == \
        {"joint_1": 0.0, "joint_2": 0.5, "joint_3": 0.0, "joint_4": 0.0}
    with pytest.raises(InvalidRequest) as e:
        joint_values(desc, {"joint_5": 0.1}, field="start")
    assert e.value.details["leader"] == "joint_4" and "joint_4" in e.value.message
    with pytest.raises(InvalidRequest) as e:
        joint_values(desc, {"elbow": 0.1}, field="goal.joints")
    assert e.value.details["field"] == "goal.joints.elbow"
    with pytest.raises(JointLimitViolation) as e:
        joint_values(desc, {"joint_4": 0.5}, field="start")
    assert e.value.details["upper"] == pytest.approx(0.0)


# -- caps: every array, object and string of a request is bounded, and the schema's
# figures are the ones in src/arduinobot/contract/caps.py --------------------------------------------

REQUEST_SCHEMAS = ("plan_request", "fk_request", "ik_request", "check_request")


def _nodes(node, path=()):
    """Every subschema with its path (the schemas are small and shallow)."""
    if isinstance(node, dict):
        yield path, node
        for k, v in node.items():
            yield from _nodes(v, (*path, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _nodes(v, (*path, i))


@pytest.mark.parametrize("name", REQUEST_SCHEMAS)
def test_every_array_object_and_string_of_a_request_is_capped(name):
    checked = 0
    for path, node in _nodes(wire.schema(name)):
        kind = node.get("type")
        if kind == "array":
            assert node.get("maxItems", caps.MAX_ITEMS + 1) <= caps.MAX_ITEMS, path
        elif kind == "object":
            assert node.get("maxProperties", caps.MAX_ITEMS + 1) <= caps.MAX_ITEMS, path
        elif kind == "string":
            assert node.get("maxLength", caps.MAX_STRING + 1) <= caps.MAX_NAME, path
        else:
            continue
        checked += 1
    assert checked >= 2  # ik: the root and position


def test_schema_caps_are_the_constants():
    plan = wire.schema("plan_request")
    p = plan["properties"]
    assert p["obstacles"]["maxItems"] == caps.MAX_OBSTACLES
    assert plan["$defs"]["joints"]["maxProperties"] == caps.MAX_JOINTS
    assert plan["$defs"]["rates"]["maxProperties"] == caps.MAX_JOINTS
    assert p["velocity_scaling"]["minimum"] == caps.MIN_SCALING
    assert p["acceleration_scaling"]["minimum"] == caps.MIN_SCALING
    assert wire.schema("check_request")["properties"]["obstacles"]["maxItems"] == \
        caps.MAX_OBSTACLES
    assert wire.schema("fk_request")["properties"]["links"]["maxItems"] == caps.MAX_LINKS
    points = wire.schema("plan_response")["properties"]["trajectory"]["properties"]["points"]
    assert points["maxItems"] == caps.MAX_SAMPLES
    for name in REQUEST_SCHEMAS:
        for figure in (caps.MAX_DEPTH, caps.MAX_ITEMS, caps.MAX_ELEMENTS, caps.MAX_STRING):
            assert str(figure) in wire.schema(name)["description"], name
    assert str(caps.MAX_SAMPLES) in p["sample_rate"]["description"]


@pytest.mark.parametrize("field", ["velocity_scaling", "acceleration_scaling"])
@pytest.mark.parametrize("value", [1e-300, 5e-324, 0.0099])
def test_scalings_below_the_floor_are_refused_naming_the_field(field, value):
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", json.dumps({"goal": {"named": "home"}, field: value}))
    assert e.value.details["field"] == field
    assert e.value.details["limit"] == caps.MIN_SCALING
    assert "0.01" in e.value.message
    assert wire.decode("plan", json.dumps({"goal": {"named": "home"}, field: 0.01}))


@pytest.mark.parametrize("payload", [b"[" * 100_000, b"[" * 1023 + b"]" * 1023,
                                     b'{"goal":' * 20_000 + b"1" + b"}" * 20_000,
                                     b'{"a":' * 9 + b"1" + b"}" * 9])
def test_deep_nesting_is_a_coded_refusal(payload):
    with pytest.raises(InvalidRequest, match="deeper"):
        wire.decode("plan", payload)


def test_a_request_as_deep_as_the_cap_is_refused_only_by_the_schema():
    nested = b'{"goal": {"named": "home"}, "obstacles": ' + b"[" * (caps.MAX_DEPTH - 1) + \
        b"]" * (caps.MAX_DEPTH - 1) + b"}"
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", nested)
    assert e.value.details["keyword"] == "type"


@pytest.mark.parametrize("body, field, cap", [
    ({"goal": {"named": "home"}, "obstacles": [1] * 60_000}, "obstacles", "MAX_ITEMS"),
    ({"goal": {"named": "home"}, "start": {f"j{i}": 0 for i in range(300)}}, "start",
     "MAX_ITEMS"),
    ({"goal": {"named": "home"}, "obstacles": [[1] * 200] * 200}, "obstacles[", "MAX_ELEMENTS"),
    ({"goal": {"named": "x" * 2000}}, "goal.named", "MAX_STRING"),
    ({"goal": {"named": "home"}, "k" * 2000: 1}, "(root)", "MAX_STRING"),
])
def test_structure_caps_name_the_field_and_the_cap(body, field, cap):
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", json.dumps(body))
    assert e.value.details["field"].startswith(field)
    assert e.value.details["cap"] == cap
    assert e.value.details["limit"] == getattr(caps, cap)
    assert str(getattr(caps, cap)) in e.value.message


def test_unknown_fields_are_echoed_a_few_and_cut_short():
    body = {"goal": {"named": "home"}, **{"z" * 200 + str(i): 1 for i in range(10)}}
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", json.dumps(body))
    d = e.value.details
    assert d["keyword"] == "additionalProperties"
    assert len(d["unknown"]) <= 8 and all(len(k) <= caps.MAX_NAME + 3 for k in d["unknown"])
    assert len(d["field"]) <= caps.MAX_NAME + 3
    assert "goal" in d["allowed"]


@pytest.mark.parametrize("payload, field", [
    ('{"goal": {"joints": {"joint_1": 0.1}, "named": "home"}}', "goal"),  # two forms
    ('{"goal": {}}', "goal"),
    ('{"goal": {"position": [0, 1, "x"]}}', "goal.position[2]"),
    ('{"goal": {"named": "home"}, "start": {"joint_1": 1e400}}', "start.joint_1"),
])
def test_refusals_inside_one_of_name_the_deepest_field(payload, field):
    with pytest.raises(InvalidRequest) as e:
        wire.decode("plan", payload)
    assert e.value.details["field"] == field


def test_a_goal_of_no_known_form_lists_the_forms():
    with pytest.raises(InvalidRequest, match=r"\{joints\}, \{named\}, \{position\}"):
        wire.decode("plan", b'{"goal": {"pose": [1, 2, 3]}}')


def test_parse_json_caps_counts_only_when_asked():
    # a trajectory to execute (up to MAX_PAYLOAD) holds more values than any request
    point = {"positions": [0.1] * 4, "velocities": [0.0] * 4, "accelerations": [0.0] * 4,
             "effort": [0.0] * 4, "time_from_start": 0.0}
    body = {"trajectory": {"trajectory": {"joint_names": ["a", "b", "c", "d"],
                                          "points": [point] * 700}}}
    raw = json.dumps(body)
    assert len(raw) < wire.MAX_PAYLOAD
    assert wire.parse_json(raw) == body
    with pytest.raises(InvalidRequest) as e:
        wire.parse_json(raw, counts=True)
    assert e.value.details["cap"] == "MAX_ITEMS"
    with pytest.raises(InvalidRequest, match="deeper"):
        wire.parse_json("[" * (caps.MAX_DEPTH + 1) + "]" * (caps.MAX_DEPTH + 1))


# -- execute requests: the same wire path (decode -> schema) -----------------------------
def test_minimal_and_full_execute_requests_pass_and_round_trip():
    point = {"positions": [0.1] * 4, "velocities": [0.0] * 4, "time_from_start": 0.0}
    traj = {"trajectory": {"joint_names": ["joint_1", "joint_2", "joint_3", "joint_4"],
                           "points": [point] * 700}}  # more values than a plan may hold
    for body in ({"plan": {"goal": {"named": "home"}}}, {"trajectory": traj},
                 {"trajectory": traj, "start_tolerance": 0.05, "move_to_start": True,
                  "client": "a1b2c3"},
                 {"plan": {"goal": {"named": "home"}}, "blend": True, "start_tolerance": 1},
                 {"plan": {"goal": {"named": "home"}}, "blend": True, "blend_lead": 2.5},
                 {"plan": {"goal": {"named": "home"}}, "on_change": "stop"}):
        assert wire.decode("execute", wire.encode(body)) == body
        assert wire.decode("execute", json.dumps(body)) == body


@pytest.mark.parametrize("payload, field", [
    ('{"plan": {}, "speed": 1}', "speed"),
    ('{"plan": {}, "start_tolerance": 0}', "start_tolerance"),
    ('{"plan": {}, "start_tolerance": 1.5}', "start_tolerance"),
    ('{"plan": {}, "start_tolerance": "0.1"}', "start_tolerance"),
    ('{"plan": {}, "move_to_start": 1}', "move_to_start"),
    ('{"plan": {}, "blend": "yes"}', "blend"),
    ('{"plan": {}, "blend": true, "blend_lead": 0}', "blend_lead"),
    ('{"plan": {}, "blend": true, "blend_lead": 31}', "blend_lead"),
    ('{"plan": {}, "on_change": "pause"}', "on_change"),
    ('{"plan": {}, "client": "not/alnum"}', "client"),
    ('{"plan": {}, "client": ""}', "client"),
    ('{"plan": []}', "plan"),
    ('{"trajectory": "traj.json"}', "trajectory"),
])
def test_execute_refusals_name_the_field(payload, field):
    with pytest.raises(InvalidRequest) as e:
        wire.decode("execute", payload)
    assert e.value.details["field"] == field


@pytest.mark.parametrize("payload", ['{}', '{"plan": {}, "trajectory": {}}',
                                     '{"start_tolerance": 0.1}'])
def test_an_execute_request_needs_exactly_one_of_trajectory_and_plan(payload):
    with pytest.raises(InvalidRequest, match=r"\{trajectory\}, \{plan\}"):
        wire.decode("execute", payload)


def test_the_execute_request_schema_is_published_and_its_ranges_are_the_services():
    from arduinobot.service.execute.io import DEFAULT_START_TOLERANCE
    s = wire.schema("execute_request")
    assert "execute_request" in wire.all_schemas()
    tol = s["properties"]["start_tolerance"]
    assert tol["default"] == DEFAULT_START_TOLERANCE
    assert s["properties"]["client"]["maxLength"] <= caps.MAX_NAME
    assert f"{wire.MAX_EXECUTE_PAYLOAD // 2**20} MiB" in s["description"]


def test_on_change_is_the_same_in_the_schema_the_service_and_the_client():
    from arduinobot.contract.outcomes import DEFAULT_ON_CHANGE, ON_CHANGE
    from arduinobot.service.execute.io import ExecuteRequest
    prop = wire.schema("execute_request")["properties"]["on_change"]
    assert tuple(prop["enum"]) == ON_CHANGE
    assert prop["default"] == DEFAULT_ON_CHANGE
    assert ExecuteRequest.decode(b'{"plan": {}}').on_change == DEFAULT_ON_CHANGE
    assert ExecuteRequest.decode(b'{"plan": {}, "on_change": "ignore"}').on_change == "ignore"
