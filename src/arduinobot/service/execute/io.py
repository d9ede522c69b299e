"""The execute keys' requests: an execute request decoded against
``src/arduinobot/contract/schema/execute_request.json`` (:func:`arduinobot.contract.wire.decode`,
as every other request), and the errors the execute wing answers with their own code
(a planner's and a robot's: :data:`CODED`, through :mod:`arduinobot.service.queries`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import zenoh

from arduinobot.contract import wire
from arduinobot.contract.errors import PlanningError
from arduinobot.contract.outcomes import DEFAULT_ON_CHANGE, OnChange
from arduinobot.execution.robots.base import RobotError

#: the errors an execute key answers as themselves (logged: a refused motion is news)
CODED: tuple[type[Exception], ...] = (PlanningError, RobotError)
DEFAULT_START_TOLERANCE = 0.01  # [rad]
DEFAULT_BLEND_LEAD = 0.8  # [s] ahead of the arm a blend is planned for (planning must finish)


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
    blend_lead: float = DEFAULT_BLEND_LEAD  # [s] ahead of the moving arm
    on_change: OnChange = DEFAULT_ON_CHANGE  # a scene change that uncertifies the rest
    task: Mapping[str, Any] | None = None  # a task's steps along it (the schema's)

    @classmethod
    def decode(cls, payload: bytes) -> ExecuteRequest:
        """Raises: InvalidRequest naming the field (the schema's refusal)."""
        body = wire.decode("execute", payload)
        return cls(body.get("trajectory"), body.get("plan"),
                   float(body.get("start_tolerance", DEFAULT_START_TOLERANCE)),
                   bool(body.get("move_to_start", False)), bool(body.get("blend", False)),
                   body.get("client"), body.get("twin"),
                   float(body.get("blend_lead", DEFAULT_BLEND_LEAD)),
                   body.get("on_change", DEFAULT_ON_CHANGE), body.get("task"))


def payload_of(query: zenoh.Query) -> bytes:
    zb = query.payload
    return zb.to_bytes() if zb is not None else b""
