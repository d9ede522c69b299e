"""A request's payload and a reply's JSON, as :class:`~arduinobot.client.client.PlannerClient`
writes and reads them: strict JSON out (NaN refused), coded errors in (each wire code its
class of :mod:`arduinobot.client.errors`)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import orjson
import zenoh

from arduinobot.client.errors import ServiceUnavailable, error_from_reply
from arduinobot.contract.ranges import RANGES
from arduinobot.contract.wire import JSON


def plan_body(request: Mapping[str, Any] | None = None, **fields: Any) -> dict[str, Any]:
    """What :meth:`PlannerClient.plan` sends: ``request`` updated with ``fields``, its
    trajectory ``packed`` unless it says otherwise."""
    return {"trajectory_format": "packed", **(request or {}), **fields}


def encode_body(body: Mapping[str, Any] | bytes | str | None) -> bytes | None:
    """A request's payload: a mapping as strict JSON (NaN refused: ValueError), bytes/str
    as they are.

    orjson first (~10x :mod:`json`); it writes NaN and infinities as ``null``, so a payload
    holding ``null`` anywhere, or anything orjson refuses (an int over 64 bits, ...), is
    encoded again by :func:`json.dumps`, which refuses them as it always has.
    """
    if isinstance(body, Mapping):
        try:
            out = orjson.dumps(body, option=_ORJSON_REQUEST)
        except TypeError:  # orjson.JSONEncodeError is one
            out = b"null"
        if b"null" not in out:
            return out
        return json.dumps(body, allow_nan=False).encode()
    if isinstance(body, str):
        return body.encode()
    return body


#: keys as :mod:`json` takes them (ints, floats, bools, None); a numpy scalar, which
#: :mod:`json` writes as the float it subclasses, goes to :mod:`json`
_ORJSON_REQUEST = orjson.OPT_NON_STR_KEYS


def planning_time(req: object) -> float:
    """[s] a request's ``planning_time`` if it gives a valid one, else 1 s."""
    v = req.get("planning_time", 1.0) if isinstance(req, Mapping) else 1.0
    return float(v) if v in RANGES["planning_time"] else 1.0


def decode_reply(reply: zenoh.Reply, key: str, wait: float) -> dict[str, Any]:
    """The JSON object of a reply on ``key`` (that waited ``wait`` seconds).

    Raises:
        ServiceError: the subclass of an error reply; ServiceUnavailable for Zenoh's own.
    """
    if reply.ok is not None:
        return orjson.loads(reply.ok.payload.to_bytes())  # strict JSON, ~3x json's speed
    err = reply.err
    assert err is not None  # a reply is either ok or an error
    text = err.payload.to_bytes().decode("utf-8", "replace")
    if str(err.encoding).startswith(JSON):
        try:
            body = json.loads(text)
        except json.JSONDecodeError:
            body = None
        if isinstance(body, dict) and "error" in body:
            raise error_from_reply(body)
    if text == "Timeout":
        raise ServiceUnavailable(
            f"'{key}': a service took the query but sent no reply within {wait:g} s "
            "(overloaded, or a long request: raise the timeout)", reason="timeout",
            details={"key": key, "timeout": wait})
    raise ServiceUnavailable(f"'{key}': Zenoh answered with an error: {text}",
                             reason="zenoh_error", details={"key": key, "zenoh": text})
