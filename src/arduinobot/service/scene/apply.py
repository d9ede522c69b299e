"""A scene apply as the instance that takes it prepares it for the leader: decoded under
its caps, and an attach or detach given the robot's state (where the link holds the
object).

The state is the apply's ``state``, else the executing robot's (``<p>/robot_state``, if
this service executes), else all joints at 0. The instance that takes the apply fills it
in before the change goes to the leader (:mod:`arduinobot.service.scene.sync`), so every instance
replays the same change to the same scene.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.caps import MAX_APPLY_PAYLOAD
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.scene.frames import Frames
from arduinobot.scene.state import StateSource

_log = logging.getLogger(__name__)

#: Deepest nesting of a scene apply (``add[i].scale[j]`` is 4 deep).
MAX_APPLY_DEPTH = 8
#: How long an attach or detach without a state waits for the executing robot's [s] (a
#: twin not opened yet answers where it starts, at once; no robot answers at once too).
ROBOT_STATE_TIMEOUT = 5.0


class SceneUnavailable(PlanningError):
    """The scene cannot take the change now (its leader or the robot did not answer):
    retry."""

    code = Code.BUSY


def decode_apply(payload: bytes) -> dict[str, Any]:
    """A scene apply request: at most :data:`MAX_APPLY_PAYLOAD` bytes of strict JSON,
    nested at most :data:`MAX_APPLY_DEPTH` deep, valid against
    ``scene_apply_request.json``.

    Raises:
        InvalidRequest: naming the field (and ``details.limit`` for a cap).
    """
    if len(payload) > MAX_APPLY_PAYLOAD:
        raise InvalidRequest(f"payload of {len(payload)} bytes exceeds the "
                             f"{MAX_APPLY_PAYLOAD}-byte cap of a scene apply",
                             details={"size": len(payload), "limit": MAX_APPLY_PAYLOAD})
    if not payload:
        raise InvalidRequest("empty payload: send a JSON object")
    try:
        value = orjson.loads(payload)
    except orjson.JSONDecodeError as e:
        raise wire._malformed(e) from None  # the same refusal as every other request's
    _check_depth(value)
    return wire.validate("scene_apply", value)


def _check_depth(value: Any) -> None:
    stack: list[tuple[Any, tuple[Any, ...], int]] = [(value, (), 1)]
    while stack:
        node, path, depth = stack.pop()
        if not isinstance(node, (dict, list)):
            continue
        if depth > MAX_APPLY_DEPTH:
            raise InvalidRequest(f"nested deeper than {MAX_APPLY_DEPTH} levels",
                                 field=wire.field_path(path) or "(root)",
                                 details={"limit": MAX_APPLY_DEPTH})
        items = node.items() if isinstance(node, dict) else enumerate(node)
        stack.extend((v, (*path, k), depth + 1) for k, v in items)


def with_robot_state(change: dict[str, Any], *, session: zenoh.Session, prefix: str,
                     robot: Frames | None) -> tuple[dict[str, Any], StateSource]:
    """``change`` (an attach, a detach or a point cloud's add) with the robot's ``state``, and where the state
    came from: the request's own, else the executing robot's (``<prefix>/robot_state``),
    else all joints at 0 (no robot serves its state).

    Raises:
        SceneUnavailable: a robot serves its state but did not give it.
    """
    if "state" in change:
        return change, "request"
    state = robot_state(session, prefix, robot)
    if state is not None:
        return {**change, "state": state}, "robot"
    return {**change, "state": {}}, "zero"


def robot_state(session: zenoh.Session, prefix: str, robot: Frames | None
                ) -> dict[str, float] | None:
    """The executing robot's actuated joints, or None if no robot serves its state
    (or the scene has no robot).

    Raises:
        SceneUnavailable: a robot serves its state but did not give it (an error, or no
            answer in :data:`ROBOT_STATE_TIMEOUT`): never guessed as all zeros.
    """
    if robot is None:
        return None
    began = time.monotonic()
    try:
        replies = list(session.get(f"{prefix}/robot_state", timeout=ROBOT_STATE_TIMEOUT))
    except zenoh.ZError:
        replies = []
    actuated = set(robot.description.robot.actuated_joints)
    failed = False
    for r in replies:
        if r.ok is None:
            failed = failed or not _no_robot(r)
            continue
        try:
            body = orjson.loads(r.ok.payload.to_bytes())
            return {str(n): float(v) for n, v in zip(body["name"], body["position"])
                    if n in actuated}
        except (orjson.JSONDecodeError, KeyError, TypeError, ValueError):
            _log.warning("scene: a robot_state reply is not a state: ignored")
    if failed or time.monotonic() - began >= 0.9 * ROBOT_STATE_TIMEOUT:
        raise SceneUnavailable("the executing robot did not give its state (where the link "
                               "holds the object): retry, or give the apply a state")
    return None  # nothing serves a robot state: all joints 0


def _no_robot(reply: zenoh.Reply) -> bool:
    """An error reply of an instance that drives no robot (``serve --no-robot``)."""
    err = reply.err
    if err is None:
        return False
    try:
        body = orjson.loads(err.payload.to_bytes())
        return body["error"]["details"].get("robot") == "none"
    except (orjson.JSONDecodeError, KeyError, TypeError, AttributeError):
        return False
