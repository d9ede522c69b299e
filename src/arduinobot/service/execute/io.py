"""The execute keys' requests and replies: an execute request decoded against
``src/arduinobot/contract/schema/execute_request.json`` (:func:`arduinobot.contract.wire.decode`, as every other
request), and coded errors answered as everywhere (``{"error": {code, message,
details}}``)."""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import PlanningError
from arduinobot.execution.robots.base import RobotError

_log = logging.getLogger(__name__)

JSON = "application/json"
DEFAULT_START_TOLERANCE = 0.01  # [rad]


@dataclass(frozen=True)
class ExecuteRequest:
    """A decoded ``<prefix>/execute`` request (see the schema): exactly one of
    ``trajectory`` (a plan reply or ``{joint_names, points}``) and ``plan`` (a v1 plan
    request)."""

    trajectory: Mapping[str, Any] | None
    plan: Mapping[str, Any] | None
    start_tolerance: float
    move_to_start: bool
    blend: bool
    client: str | None
    twin: Mapping[str, Any] | None = None  # a task's objects for a twin (the schema's)

    @classmethod
    def decode(cls, payload: bytes) -> ExecuteRequest:
        """Raises: InvalidRequest naming the field (the schema's refusal)."""
        body = wire.decode("execute", payload)
        return cls(body.get("trajectory"), body.get("plan"),
                   float(body.get("start_tolerance", DEFAULT_START_TOLERANCE)),
                   bool(body.get("move_to_start", False)), bool(body.get("blend", False)),
                   body.get("client"), body.get("twin"))


def payload_of(query: zenoh.Query) -> bytes:
    zb = query.payload
    return zb.to_bytes() if zb is not None else b""


def reply_err(query: zenoh.Query, code: str, message: str,
              details: Mapping[str, Any] | None = None) -> None:
    query.reply_err(wire.encode({"error": {"code": code, "message": message,
                                           "details": dict(details or {})}}), encoding=JSON)


@contextmanager
def answering(query: zenoh.Query, where: str, internal: str) -> Iterator[None]:
    """A coded error (planner or robot) in the block answers ``query`` as itself; any
    other is logged and answered INTERNAL with the message ``internal``."""
    try:
        yield
    except (PlanningError, RobotError) as e:
        # said in the service's log too: a refused motion is news to whoever watches it
        _log.warning("%s: refused %s: %s", where, e.code, e.message)
        reply_err(query, e.code, e.message, e.details)
    except Exception:  # noqa: BLE001 -- logged; the querier gets INTERNAL
        _log.exception("%s: %s", where, internal)
        reply_err(query, Code.INTERNAL, internal)
