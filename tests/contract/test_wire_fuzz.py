"""Property-based tests of the wire decoder and the request checks (hypothesis).

Whatever arrives, :func:`arduinobot.contract.wire.decode` returns a dict or raises
:class:`~arduinobot.contract.errors.InvalidRequest`, and the checks a worker runs next (requests.py,
plan_io.py, the fk/check handlers on the real FCL world) raise only coded
:class:`~arduinobot.contract.errors.PlanningError`s. Derandomized: every run draws the same examples.
"""

from __future__ import annotations

import json
import math
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from arduinobot.contract import caps, wire
from arduinobot.contract.errors import InvalidRequest, PlanningError
from tests.helpers.json_paths import json_get, json_paths

SETTINGS = settings(derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
KINDS = ("plan", "fk", "ik", "check")

VALID: dict[str, list[dict[str, Any]]] = {
    "plan": [
        {"goal": {"named": "reach_left"}},
        {"goal": {"joints": {"joint_1": 0.3, "joint_2": -0.2}}, "start": {"joint_3": 0.1},
         "planning_time": 0.5, "seed": 3, "sample_rate": 50, "profile": "time_optimal"},
        {"goal": {"position": [0.0, 1.0, 1.2]}, "group": "arm", "velocity_scaling": 0.5,
         "acceleration_scaling": 0.25,
         "obstacles": [{"id": "table", "shape": "box", "size": [1, 1, 0.1],
                        "xyz": [0, 1, 0.5], "rpy": [0, 0, 0.3]},
                       {"id": "ball", "shape": "sphere", "radius": 0.1, "xyz": [2, 2, 2]},
                       {"id": "post", "shape": "cylinder", "radius": 0.05, "length": 1,
                        "xyz": [-2, 0, 0]}]},
        {"goal": {"named": "home"}, "start_velocity": {"joint_1": 0.2},
         "start_acceleration": {"joint_2": -0.5}},
    ],
    "fk": [{"joints": {"joint_1": 0.5}}, {"joints": {}, "links": ["base_link", "claw_support"]},
           {}],
    "ik": [{"position": [0.0, 1.0, 1.2]}],
    "check": [{"joints": {"joint_2": 0.4}},
              {"joints": {"joint_1": 0.1}, "padding": 0.02,
               "obstacles": [{"id": "b", "shape": "sphere", "radius": 0.2,
                              "xyz": [0, 1, 1.6]}]}],
}

# values that have broken decoders, schemas and numeric code before
NASTY_NUMBERS = [0, -0.0, 1, -1, 5e-324, 1e-300, -1e-300, 1e-12, 1e300, -1e300, 1.7976931348623157e308,
                 2**53 + 1, 2**63 - 1, -(2**63), 2**64 - 1, 4294967295, 4294967296, 0.5, 7.0, 1000.0,
                 1000.0000001, 60.0, 60.000001, 0.01, 0.009999999, 100.0, -100.0, 3.141592653589793]
NASTY_STRINGS = ["", " ", "home", "joint_1", "joint_5", "base_link", "\u0000", "\u202e",
                 "é", "日本", "\U0001f916", "a" * 64, "a" * 65, "x" * 2000, "all", "RRTConnect",
                 "box", "mesh", "../../etc/passwd", "$*", "**", "NaN", "Infinity", "1e999"]
# same-type mutations reach past the schema into the request checks
numbers = st.one_of(st.sampled_from(NASTY_NUMBERS), st.floats(-10, 10), st.floats(-2, 2),
                    st.floats(allow_nan=False, allow_infinity=False))
strings = st.one_of(st.sampled_from(NASTY_STRINGS), st.text(max_size=20))
json_scalars = st.one_of(st.none(), st.booleans(), st.sampled_from(NASTY_NUMBERS),
                         st.integers(min_value=-(2**63), max_value=2**64 - 1),
                         st.floats(allow_nan=False, allow_infinity=False),
                         st.sampled_from(NASTY_STRINGS), st.text(max_size=20))
json_values = st.recursive(json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=6), st.dictionaries(st.text(max_size=8), inner, max_size=6)),
    max_leaves=30)


def _decode_or_refuse(kind: str, payload: bytes | str) -> dict[str, Any] | None:
    """decode's result, or None if it refused with a coded InvalidRequest; anything
    else propagates and fails the test."""
    try:
        out = wire.decode(kind, payload)  # type: ignore[arg-type]
    except InvalidRequest as e:
        assert e.code == "INVALID_REQUEST" and e.message
        json.dumps(e.details, allow_nan=False)  # the refusal itself goes on the wire
        return None
    assert isinstance(out, dict)
    return out


# -- the decoder alone -----------------------------------------------------------------

@settings(SETTINGS, max_examples=400)
@given(kind=st.sampled_from(KINDS), payload=st.binary(max_size=512))
def test_any_bytes_decode_to_a_dict_or_a_coded_refusal(kind, payload):
    _decode_or_refuse(kind, payload)


@SETTINGS
@given(kind=st.sampled_from(KINDS), text=st.text(max_size=300))
def test_any_text_decodes_to_a_dict_or_a_coded_refusal(kind, text):
    _decode_or_refuse(kind, text)


@SETTINGS
@given(kind=st.sampled_from(KINDS), value=json_values)
def test_any_json_value_decodes_to_a_dict_or_a_coded_refusal(kind, value):
    out = _decode_or_refuse(kind, json.dumps(value))
    if out is not None:
        assert out == value


@SETTINGS
@given(kind=st.sampled_from(KINDS), depth=st.integers(caps.MAX_DEPTH + 1, 3000),
       opener=st.sampled_from(["[", '{"a":']))
def test_nesting_past_the_cap_is_refused_whatever_the_depth(kind, depth, opener):
    closer = "]" if opener == "[" else "}"
    payload = opener * depth + "0" + closer * depth
    with pytest.raises(InvalidRequest, match="deeper"):
        wire.decode(kind, payload)


@SETTINGS
@given(kind=st.sampled_from(KINDS), n=st.integers(caps.MAX_ITEMS + 1, 20_000),
       where=st.sampled_from(["obstacles", "joints", "links", "position", "x"]),
       as_object=st.booleans())
def test_any_container_over_the_item_cap_is_refused_naming_it(kind, n, where, as_object):
    inner: Any = {f"k{i}": 0 for i in range(n)} if as_object else [0] * n
    with pytest.raises(InvalidRequest) as e:
        wire.decode(kind, json.dumps({where: inner}))
    assert e.value.details["cap"] == "MAX_ITEMS" and e.value.details["field"] == where


@SETTINGS
@given(kind=st.sampled_from(KINDS), width=st.integers(2, caps.MAX_ITEMS),
       rows=st.integers(2, caps.MAX_ITEMS))
def test_the_total_value_cap_holds_for_any_shape(kind, width, rows):
    assume(width * rows + rows > caps.MAX_ELEMENTS)
    with pytest.raises(InvalidRequest) as e:
        wire.decode(kind, json.dumps({"obstacles": [[0] * width] * rows}))
    assert e.value.details["cap"] == "MAX_ELEMENTS"


@SETTINGS
@given(kind=st.sampled_from(KINDS), number=st.sampled_from(
    ["1e309", "-1e309", "1" * 400, "NaN", "Infinity", "-Infinity", "1e999999999"]))
def test_non_finite_numbers_are_refused_anywhere(kind, number):
    with pytest.raises(InvalidRequest, match="finite"):
        wire.decode(kind, '{"joints": {"joint_1": ' + number + '}}')


# -- mutations of valid requests, through the checks a worker runs ---------------------

def _replace(value: Any, path: tuple[Any, ...], new: Any) -> Any:
    if not path:
        return new
    head, rest = path[0], path[1:]
    if isinstance(value, dict):
        return {**value, head: _replace(value[head], rest, new)}
    out = list(value)
    out[head] = _replace(value[head], rest, new)
    return out


def _delete(value: Any, path: tuple[Any, ...]) -> Any:
    if not path:
        return value
    head, rest = path[0], path[1:]
    if rest:
        return _replace(value, (head,), _delete(value[head], rest))
    if isinstance(value, dict):
        return {k: v for k, v in value.items() if k != head}
    return [v for i, v in enumerate(value) if i != head]


@st.composite
def mutated(draw: Any, kind: str) -> dict[str, Any]:
    value: Any = draw(st.sampled_from(VALID[kind]))
    for _ in range(draw(st.integers(1, 3))):
        paths = json_paths(value)
        op = draw(st.sampled_from(["same_type", "same_type", "replace", "delete", "add"]))
        leaves = [p for p in paths if not isinstance(json_get(value, p), (dict, list))]
        path = draw(st.sampled_from(leaves if op == "same_type" and leaves else paths))
        old = json_get(value, path)
        if op == "same_type" and isinstance(old, (int, float)) and not isinstance(old, bool):
            value = _replace(value, path, draw(numbers))
        elif op == "same_type" and isinstance(old, str):
            value = _replace(value, path, draw(strings))
        elif op in ("replace", "same_type"):
            value = _replace(value, path, draw(json_values))
        elif op == "delete":
            value = _delete(value, path)
        else:
            target = draw(st.sampled_from([p for p in paths if _is_dict(value, p)] or [()]))
            key = draw(st.one_of(st.sampled_from(NASTY_STRINGS), st.text(max_size=10)))
            new = draw(json_values)
            value = _replace(value, target, {**json_get(value, target), key: new}) \
                if _is_dict(value, target) else value
    return value


def _is_dict(value: Any, path: tuple[Any, ...]) -> bool:
    return isinstance(json_get(value, path), dict)


@pytest.fixture(scope="module")
def handlers():
    from arduinobot.description import load_description
    from arduinobot.service.plan.handlers import Handlers
    return Handlers(load_description())


def _work(handlers: Any, kind: str, data: dict[str, Any]) -> None:
    """What a worker does with a decoded request, short of planning: every failure a
    coded PlanningError (anything else fails the test)."""
    from arduinobot.service.plan.plan_io import plan_request
    try:
        if kind == "plan":
            req = plan_request(handlers.description, data)
            handlers._motion_planner().validate(req)
        else:
            body = handlers.handle(kind, data)
            json.dumps(body, allow_nan=False)
    except PlanningError as e:
        assert e.code != "INTERNAL", e


@settings(SETTINGS, max_examples=600)
@given(data=st.data(), kind=st.sampled_from(KINDS))
def test_any_mutation_of_a_valid_request_is_answered_or_refused_with_a_code(handlers, data,
                                                                             kind):
    value = data.draw(mutated(kind))
    out = _decode_or_refuse(kind, json.dumps(value))
    if out is not None:
        _work(handlers, kind, out)


@SETTINGS
@given(kind=st.sampled_from(KINDS), index=st.integers(0, 3))
def test_the_valid_requests_pass(handlers, kind, index):
    valid = VALID[kind][index % len(VALID[kind])]
    assert wire.decode(kind, json.dumps(valid)) == valid
    _work(handlers, kind, valid)


@SETTINGS
@given(field=st.sampled_from(["velocity_scaling", "acceleration_scaling"]),
       value=st.floats(min_value=0.0, max_value=1.0, exclude_max=True))
def test_scalings_are_refused_below_the_floor_and_kept_above(handlers, field, value):
    body = json.dumps({"goal": {"named": "home"}, field: value})
    if value < caps.MIN_SCALING:
        with pytest.raises(InvalidRequest) as e:
            wire.decode("plan", body)
        assert e.value.details["field"] == field
    else:
        req = wire.decode("plan", body)
        assert math.isclose(req[field], value)
        _work(handlers, "plan", req)
