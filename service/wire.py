"""Strict JSON in and out: size cap, no NaN/Infinity, JSON Schema validation.

Every refusal is a :class:`planner.errors.InvalidRequest` naming the field path
(``obstacles[0].size[1]``), so the service and ``arduinobot plan --local`` refuse alike.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from functools import cache
from importlib import resources
from typing import Any, Literal

import jsonschema
import orjson

from planner.errors import InvalidRequest

#: Largest request payload accepted [bytes].
MAX_PAYLOAD = 256 * 1024

Kind = Literal["plan", "fk", "ik", "check"]
SCHEMA_NAMES = ("plan_request", "plan_response", "error", "fk_request", "fk_response",
                "ik_request", "ik_response", "check_request", "check_response")


@cache
def schema(name: str) -> dict[str, Any]:
    """The JSON Schema ``service/schema/<name>.json`` as a dict."""
    if name not in SCHEMA_NAMES:
        raise KeyError(name)
    text = resources.files("service").joinpath("schema", f"{name}.json").read_text("utf-8")
    return json.loads(text)


def all_schemas() -> dict[str, dict[str, Any]]:
    """Every published schema by name (what ``<prefix>/schema`` serves)."""
    return {n: schema(n) for n in SCHEMA_NAMES}


@cache
def _validator(name: str) -> jsonschema.Draft202012Validator:
    s = schema(name)
    jsonschema.Draft202012Validator.check_schema(s)
    return jsonschema.Draft202012Validator(s)


def _refuse_constant(token: str) -> float:
    raise ValueError(f"{token} is not allowed (numbers must be finite)")


def field_path(parts: Any) -> str:
    """``['obstacles', 0, 'size', 1]`` -> ``'obstacles[0].size[1]'``."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def check_size(size: int) -> None:
    """Refuse a payload of ``size`` bytes over :data:`MAX_PAYLOAD`."""
    if size > MAX_PAYLOAD:
        raise InvalidRequest(f"payload of {size} bytes exceeds the {MAX_PAYLOAD}-byte cap",
                             details={"size": size, "limit": MAX_PAYLOAD})


def parse_json(payload: bytes | str) -> Any:
    """Decode a payload: at most :data:`MAX_PAYLOAD` bytes, UTF-8, strict JSON.

    Raises:
        InvalidRequest: over the size cap (``details.limit``), not UTF-8, malformed JSON
            (``details.line``/``column``), or a NaN/Infinity token or an overflowing number.
    """
    size = len(payload.encode("utf-8") if isinstance(payload, str) else payload)
    check_size(size)
    if size == 0:
        raise InvalidRequest("empty payload: send a JSON object")
    try:
        text = payload.decode("utf-8") if isinstance(payload, bytes) else payload
        value = json.loads(text, parse_constant=_refuse_constant)
    except UnicodeDecodeError as e:
        raise InvalidRequest(f"payload is not UTF-8: {e}") from None
    except json.JSONDecodeError as e:
        raise InvalidRequest(f"malformed JSON: {e.msg} at line {e.lineno} column {e.colno}",
                             details={"line": e.lineno, "column": e.colno}) from None
    except ValueError as e:  # parse_constant, or a number too long to convert
        raise InvalidRequest(f"malformed JSON: {e}") from None
    check_finite(value)
    return value


def check_finite(value: Any, path: tuple[Any, ...] = ()) -> None:
    """Refuse non-finite floats anywhere (``1e999`` parses to inf), naming the field."""
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InvalidRequest(f"{value!r} is not a finite number", field=field_path(path)
                                 or "(root)")
    elif isinstance(value, Mapping):
        for k, v in value.items():
            check_finite(v, (*path, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            check_finite(v, (*path, i))


def validate(kind: Kind, value: Any) -> dict[str, Any]:
    """Validate a decoded request against ``<kind>_request.json``; returns it.

    Raises:
        InvalidRequest: the most relevant schema violation, with its field path, the
            failing keyword and (for unknown fields) the field's name.
    """
    v = _validator(f"{kind}_request")
    err = jsonschema.exceptions.best_match(v.iter_errors(value))
    if err is None:
        return value
    path = list(err.absolute_path)
    details: dict[str, object] = {"keyword": err.validator}
    if err.validator == "additionalProperties" and isinstance(err.instance, Mapping):
        allowed = set(err.schema.get("properties", {}))
        extra = sorted(k for k in err.instance if k not in allowed)
        if extra:
            path.append(extra[0])
            details["unknown"] = extra
            details["allowed"] = sorted(allowed)
            raise InvalidRequest(f"unknown field (allowed: {', '.join(sorted(allowed))})",
                                 field=field_path(path), details=details)
    raise InvalidRequest(_short(err.message), field=field_path(path) or "(root)",
                         details=details)


def _short(msg: str, limit: int = 300) -> str:
    return msg if len(msg) <= limit else msg[:limit] + "..."


def decode(kind: Kind, payload: bytes | str) -> dict[str, Any]:
    """:func:`parse_json` then :func:`validate`: the whole cheap, description-free check."""
    return validate(kind, parse_json(payload))


def encode(value: Any, *, finite: bool = False) -> bytes:
    """Compact JSON; refuses NaN/Infinity rather than emitting invalid JSON.

    ``finite=True``: the caller guarantees every number is finite (orjson would write
    NaN as null), so the large plan replies take orjson, ~20x faster than :mod:`json`.
    """
    if finite:
        return orjson.dumps(value, default=_plain, option=orjson.OPT_SERIALIZE_NUMPY)
    return json.dumps(value, allow_nan=False, separators=(",", ":"),
                      default=_plain).encode("utf-8")


def _plain(o: Any) -> Any:
    # numpy scalars and arrays (planner details) become plain JSON values.
    if hasattr(o, "tolist"):
        return o.tolist()
    if isinstance(o, (tuple, set, frozenset)):
        return list(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")
