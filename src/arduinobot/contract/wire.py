"""Strict JSON in and out: size and structure caps, no NaN/Infinity, JSON Schema validation.

Every refusal is a :class:`arduinobot.contract.errors.InvalidRequest` naming the field path
(``obstacles[0].size[1]``), so the service and ``arduinobot plan --local`` refuse alike.
Decoding is bounded before any per-element work: the payload's size
(:data:`arduinobot.contract.caps.MAX_PAYLOAD`), then orjson (C, no Python recursion, nesting over
1024 refused), then :func:`arduinobot.contract.caps.check_structure` (depth, element count, string
length), and only then the schema. Whatever bytes arrive, :func:`decode` returns a dict
or raises :class:`~arduinobot.contract.errors.InvalidRequest`; nothing else.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from functools import cache
from importlib import resources
from typing import Any, Literal

import jsonschema
import jsonschema_rs
import orjson

from arduinobot.contract.caps import (
    MAX_DEPTH,
    MAX_EXECUTE_PAYLOAD,
    MAX_PAYLOAD,
    check_structure,
    field_path,
)
from arduinobot.contract.errors import InvalidRequest, unknown_names

__all__ = ["JSON", "MAX_EXECUTE_PAYLOAD", "MAX_PAYLOAD", "Kind", "SCHEMA_NAMES", "all_schemas", "check_finite", "check_size",
           "decode", "encode", "error_json", "field_path", "parse_json", "payload_cap",
           "schema", "validate", "validator"]

#: the encoding of every request and reply payload (Zenoh's encoding field)
JSON = "application/json"


def error_json(code: str, message: str, details: Mapping[str, Any] | None = None
               ) -> dict[str, Any]:
    """An error reply's body (error.json): ``{"error": {code, message, details}}``."""
    return {"error": {"code": str(code), "message": message, "details": dict(details or {})}}

Kind = Literal["plan", "fk", "ik", "check", "execute", "task"]
SCHEMA_NAMES = ("plan_request", "plan_response", "error", "fk_request", "fk_response",
                "ik_request", "ik_response", "check_request", "check_response",
                "execute_request", "scene_apply_request", "scene_apply_response",
                "scene_response", "task_request", "task_response", "perceive_request",
                "perceive_response")
#: Requests whose element counts are not capped: an execute request carries a whole
#: trajectory (thousands of points), bounded by the payload cap and read point by point.
_UNCOUNTED: frozenset[str] = frozenset({"execute"})
#: what :func:`validate` takes beyond the work kinds: the scene's apply request
#: (decoded by :func:`arduinobot.service.scene.apply.decode_apply`, under its own size caps)
#: and perceive's (an image: :mod:`arduinobot.service.perceive`)
OtherKind = Literal["scene_apply", "perceive"]
#: Schema keywords whose figure is a cap or a bound: their refusals carry it as
#: ``details.limit``.
_LIMIT_KEYWORDS = ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum", "maxItems",
                   "minItems", "maxLength", "minLength", "maxProperties", "minProperties")
#: Unknown field names echoed in a refusal, at most.
_ECHO = 8


@cache
def schema(name: str) -> dict[str, Any]:
    """The JSON Schema ``src/arduinobot/contract/schema/<name>.json`` as a dict."""
    if name not in SCHEMA_NAMES:
        raise KeyError(name)
    text = (resources.files("arduinobot.contract") / "schema" / f"{name}.json").read_text("utf-8")
    return json.loads(text)


def all_schemas() -> dict[str, dict[str, Any]]:
    """Every published schema by name (what ``<prefix>/schema`` serves)."""
    return {n: schema(n) for n in SCHEMA_NAMES}


@cache
def validator(name: str) -> jsonschema_rs.Draft202012Validator:
    """The validator of schema ``name``, built once: requests' (:func:`validate`) and, in
    the client, replies'."""
    s = schema(name)
    jsonschema.Draft202012Validator.check_schema(s)  # the reference implementation's check
    # jsonschema-rs: ~300x faster than jsonschema (a valid request of 256 obstacles in
    # ~0.15 ms instead of ~45 ms), and it stops at the first violation
    return jsonschema_rs.Draft202012Validator(s)


def payload_cap(kind: str) -> int:
    """The largest payload [bytes] of a ``kind`` request: :data:`MAX_EXECUTE_PAYLOAD` for
    an execute request (a whole trajectory), :data:`MAX_PAYLOAD` for every other."""
    return MAX_EXECUTE_PAYLOAD if kind == "execute" else MAX_PAYLOAD


def check_size(size: int, *, limit: int = MAX_PAYLOAD) -> None:
    """Refuse a payload of ``size`` bytes over ``limit`` (:func:`payload_cap`)."""
    if size > limit:
        raise InvalidRequest(f"payload of {size} bytes exceeds the {limit}-byte cap",
                             details={"size": size, "limit": limit})


def parse_json(payload: bytes | str, *, counts: bool = False, limit: int = MAX_PAYLOAD
               ) -> Any:
    """Decode a payload: at most :data:`MAX_PAYLOAD` bytes, UTF-8, strict JSON, nested
    at most :data:`arduinobot.contract.caps.MAX_DEPTH` deep, no string over
    :data:`arduinobot.contract.caps.MAX_STRING`.

    Args:
        counts: also cap element counts (:data:`arduinobot.contract.caps.MAX_ITEMS` per array or
            object, :data:`arduinobot.contract.caps.MAX_ELEMENTS` in all), as for plan/fk/ik/check
            requests; off for payloads such as a trajectory to execute.
        limit: the size cap [bytes] (:func:`payload_cap`).

    Raises:
        InvalidRequest: over the size cap (``details.limit``), not UTF-8, malformed JSON
            (``details.line``/``column``), a NaN/Infinity token or a number that
            overflows a double, nested too deep, too many values or too long a string.
    """
    if isinstance(payload, str):
        try:
            payload = payload.encode("utf-8")
        except UnicodeEncodeError as e:  # a str holding lone surrogates
            raise InvalidRequest(f"payload is not UTF-8: {e.reason}") from None
    size = len(payload)
    check_size(size, limit=limit)
    if size == 0:
        raise InvalidRequest("empty payload: send a JSON object")
    try:
        # orjson: strict (no NaN/Infinity, no lone surrogates), iterative, ~10x json
        value = orjson.loads(payload)
    except orjson.JSONDecodeError as e:
        raise _malformed(e) from None
    check_structure(value, counts=counts)
    return value


#: Stands in for a number too large for a double while :func:`_overflow_field` finds it.
_OVERFLOW = "\u0000overflow"
_NUMBER_CHARS = frozenset("+-0123456789.eE")


def _overflow_field(doc: str, pos: int) -> str | None:
    """The field path of the number at character ``pos`` of ``doc`` (one orjson refused
    as too large for a double), or None if it cannot be told."""
    end = pos
    while end < len(doc) and doc[end] in _NUMBER_CHARS:
        end += 1
    try:
        value = orjson.loads(doc[:pos] + orjson.dumps(_OVERFLOW).decode() + doc[end:])
        check_structure(value)  # the count caps too: the search below stays short
    except (orjson.JSONDecodeError, InvalidRequest):
        return None  # a later fault or a cap: the line and column still say where
    stack: list[tuple[Any, tuple[Any, ...]]] = [(value, ())]
    while stack:  # bounded: check_structure passed
        node, path = stack.pop()
        if node == _OVERFLOW:
            return field_path(path) or "(root)"
        if isinstance(node, dict):
            stack.extend((v, (*path, k)) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((v, (*path, i)) for i, v in enumerate(node))
    return None


def _malformed(e: orjson.JSONDecodeError) -> InvalidRequest:
    """A decode error as the refusal a user can act on (line and column included)."""
    where = {"line": e.lineno, "column": e.colno}
    at = f"line {e.lineno} column {e.colno}"
    doc = e.doc if isinstance(e.doc, str) else ""  # orjson's pos counts characters of it
    token = next((t for t in ("NaN", "Infinity") if doc.startswith(t, e.pos)), None)
    if token is not None:
        return InvalidRequest(f"{token} is not allowed: numbers must be finite ({at})",
                              details=where)
    if "infinity" in e.msg:
        return InvalidRequest(f"a number too large for a double: numbers must be finite "
                              f"({at})", field=_overflow_field(doc, e.pos), details=where)
    if "depth limit" in e.msg:  # over 1024 levels: orjson stops before check_structure
        return InvalidRequest(f"nested deeper than {MAX_DEPTH} levels of arrays and objects "
                              f"({at})", details={**where, "limit": MAX_DEPTH,
                                                  "cap": "MAX_DEPTH"})
    if "UTF-8" in e.msg or "surrogate" in e.msg:
        return InvalidRequest(f"payload is not UTF-8: {e.msg} ({at})", details=where)
    return InvalidRequest(f"malformed JSON: {e.msg} at {at}", details=where)


def check_finite(value: Any, path: tuple[Any, ...] = ()) -> None:
    """Refuse non-finite floats anywhere, naming the field (a reply's numbers: decoded
    requests cannot hold one, :func:`parse_json` refuses them)."""
    t = type(value)  # exact types first: an abc's isinstance is ~10x slower
    if t is float or (t is not int and t is not str and isinstance(value, float)):
        if not math.isfinite(value):
            raise InvalidRequest(f"{value!r} is not a finite number", field=field_path(path)
                                 or "(root)")
    elif t is int or t is str or t is bool or value is None:
        return
    elif t is dict or isinstance(value, Mapping):
        for k, v in value.items():
            check_finite(v, (*path, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            check_finite(v, (*path, i))


def validate(kind: Kind | OtherKind, value: Any) -> dict[str, Any]:
    """Validate a decoded request against ``<kind>_request.json``; returns it.

    Raises:
        InvalidRequest: the first schema violation (inside a ``oneOf``, the deepest
            violation of the alternative that matched furthest), with its field path,
            the failing keyword, the bound it broke (``details.limit``) and, for
            unknown fields, their names.
    """
    try:
        validator(f"{kind}_request").validate(value)
    except jsonschema_rs.ValidationError as e:
        raise _refusal(_deepest(e), f"{kind}_request") from None
    return value


def _deepest(err: jsonschema_rs.ValidationError) -> jsonschema_rs.ValidationError:
    """Inside ``oneOf``/``anyOf``, the violation the user most likely meant, recursively:
    from the alternative that got furthest into the request (``goal.joints.<name>``
    rather than ``goal``), else the one alternative with the fewest violations; the
    summary when alternatives tie."""
    for _ in range(MAX_DEPTH * 4):  # schemas nest a few levels; bounded all the same
        branches = [b for b in (getattr(err.kind, "context", None) or ()) if b]
        if not branches:
            return err

        def rank(branch: list[Any]) -> tuple[int, int]:
            return max(len(x.instance_path) for x in branch), -len(branch)
        best, *others = sorted(branches, key=rank, reverse=True)
        if others and rank(others[0]) == rank(best):
            return err  # as close to one alternative as to another: the summary says it
        err = max(best, key=lambda x: len(x.instance_path))
    return err


def _refusal(err: jsonschema_rs.ValidationError, name: str) -> InvalidRequest:
    path = list(err.instance_path)
    keyword = err.schema_path[-1] if err.schema_path else "type"
    details: dict[str, object] = {"keyword": keyword}
    limit = getattr(err.kind, "limit", None)
    if keyword in _LIMIT_KEYWORDS and limit is not None:
        details["limit"] = limit
    unexpected = getattr(err.kind, "unexpected", None)
    if keyword == "additionalProperties" and unexpected:
        extra = sorted(str(k) for k in unexpected)
        allowed = sorted(_allowed(name, list(err.schema_path)))
        # a few names, cut short: a refusal must not echo a request's worth of keys
        details["unknown"] = [field_path([k]) for k in extra[:_ECHO]]
        details["allowed"] = allowed
        return InvalidRequest(f"unknown field {unknown_names(extra[:1], allowed)} (allowed: "
                              f"{', '.join(allowed)})",
                              field=field_path([*path, extra[0]]), details=details)
    message = err.message
    if keyword in ("oneOf", "anyOf"):
        forms = _forms(name, list(err.schema_path))
        if forms:
            message = f"must be exactly one of: {', '.join(forms)}"
            # a mistyped key ({"jionts": ...}) matches no alternative: name the closest
            keys = _alternatives_keys(name, list(err.schema_path))
            given = err.instance if isinstance(err.instance, Mapping) else {}
            typos = [k for k in given if isinstance(k, str) and k not in keys]
            if typos and keys:
                message += f"; unknown {unknown_names(typos[:_ECHO], keys)}"
    if len(message) > 300:
        message = message[:300] + "..."
    return InvalidRequest(message, field=field_path(path) or "(root)", details=details)


def _forms(name: str, schema_path: list[Any]) -> list[str]:
    """``oneOf`` alternatives that are objects, as ``{joints}``, ``{named}``, ..."""
    node = _schema_at(name, schema_path)
    alts = node if isinstance(node, list) else []
    return ["{" + ", ".join(alt["required"]) + "}" for alt in alts
            if isinstance(alt, Mapping) and alt.get("required")]


def _alternatives_keys(name: str, schema_path: list[Any]) -> set[str]:
    """Every property name of the ``oneOf`` alternatives at ``schema_path``."""
    node = _schema_at(name, schema_path)
    return {k for alt in (node if isinstance(node, list) else [])
            if isinstance(alt, Mapping) for k in alt.get("properties", {})}


def _allowed(name: str, schema_path: list[Any]) -> list[str]:
    """The property names schema ``name`` allows where ``additionalProperties`` failed
    (``schema_path``, with references resolved, ends with that keyword)."""
    node = _schema_at(name, schema_path[:-1])
    return list(node.get("properties", {})) if isinstance(node, Mapping) else []


def _schema_at(name: str, schema_path: list[Any]) -> Any:
    """The part of schema ``name`` at ``schema_path``, or None if there is none."""
    node: Any = schema(name)
    for part in schema_path:
        try:
            node = node[part]
        except (KeyError, IndexError, TypeError):
            return None
    return node


def decode(kind: Kind, payload: bytes | str) -> dict[str, Any]:
    """:func:`parse_json` (with the count caps, but for an execute request's trajectory)
    then :func:`validate`: the whole cheap, description-free check, bounded to a few
    milliseconds whatever the payload."""
    return validate(kind, parse_json(payload, counts=kind not in _UNCOUNTED,
                                     limit=payload_cap(kind)))


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
