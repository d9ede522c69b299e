"""ROS 2 actions over rmw_zenoh: three services and two topics.

rmw_zenoh has no action entity (docs/design.md @ 99a6a2bd10b949052f4f12c5854825dc005e95a5,
"Actions": "actions are composed of several services and publishers/subscriptions");
rcl_action names them ``<action>/_action/send_goal`` (``<Action>_SendGoal``),
``.../cancel_goal`` (action_msgs/srv/CancelGoal), ``.../get_result``
(``<Action>_GetResult``), ``.../feedback`` (``<Action>_FeedbackMessage``) and
``.../status`` (action_msgs/msg/GoalStatusArray, transient_local depth 1).

:class:`ActionServer` runs each accepted goal's ``execute(handle)`` on a thread of its own;
``get_result`` requests wait (deferred replies) until the goal ends. Bad input is coded and
logged and the server keeps serving: a goal id already in use is rejected; a cancel of an
unknown goal answers ``ERROR_UNKNOWN_GOAL_ID``, of an ended one ``ERROR_GOAL_TERMINATED``,
of nothing cancellable ``ERROR_REJECTED``; a result request for an unknown goal answers
``STATUS_UNKNOWN`` at once (as rcl_action does). :class:`ActionClient` is the other side.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid as uuidlib
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.ros2.errors import EntityClosed, GoalAlreadyEnded, InvalidOption
from arduinobot.ros2.wire.node import Node
from arduinobot.ros2.wire.qos import ACTION_STATUS
from arduinobot.ros2.wire.services import PendingRequest
from arduinobot.ros2.wire.topics import MessageInfo

log = logging.getLogger(__name__)

CANCEL_GOAL = "action_msgs/srv/CancelGoal"
GOAL_STATUS_ARRAY = "action_msgs/msg/GoalStatusArray"
_CANCEL_GOAL_SRV = """action_msgs/msg/GoalInfo goal_info
---
int8 ERROR_NONE=0
int8 ERROR_REJECTED=1
int8 ERROR_UNKNOWN_GOAL_ID=2
int8 ERROR_GOAL_TERMINATED=3
int8 return_code
action_msgs/msg/GoalInfo[] goals_canceling
"""

# action_msgs/msg/GoalStatus
STATUS_UNKNOWN, STATUS_ACCEPTED, STATUS_EXECUTING, STATUS_CANCELING = 0, 1, 2, 3
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 4, 5, 6
TERMINAL = (STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED)
# action_msgs/srv/CancelGoal
ERROR_NONE, ERROR_REJECTED, ERROR_UNKNOWN_GOAL_ID, ERROR_GOAL_TERMINATED = 0, 1, 2, 3


def action_endpoints(name: str) -> dict[str, str]:
    """The five names an action ``name`` uses (relative names stay relative)."""
    return {part: f"{name}/_action/{part}"
            for part in ("send_goal", "cancel_goal", "get_result", "feedback", "status")}


def ensure_action_msgs(node: Node) -> None:
    """Register action_msgs/srv/CancelGoal (rosbags' stores carry no services)."""
    if CANCEL_GOAL not in node.types:
        node.types.register_srv(CANCEL_GOAL, _CANCEL_GOAL_SRV)


def _stamp(node: Node, ns: int) -> Any:
    return node.types.message("builtin_interfaces/msg/Time", sec=ns // 1_000_000_000,
                              nanosec=ns % 1_000_000_000)


def _uuid(node: Node, goal_id: bytes) -> Any:
    return node.types.message("unique_identifier_msgs/msg/UUID",
                              uuid=np.frombuffer(goal_id, dtype=np.uint8).copy())


class GoalHandle:
    """One goal on the server. ``execute`` reads :attr:`goal`, calls
    :meth:`publish_feedback`, watches :attr:`cancel_requested`, and ends the goal with
    :meth:`succeed`, :meth:`abort` or :meth:`canceled` (else it is aborted)."""

    def __init__(self, server: ActionServer, goal_id: bytes, goal: Any) -> None:
        self.goal_id, self.goal = goal_id, goal
        self.accepted_ns = time.time_ns()
        self.status = STATUS_ACCEPTED
        self.result: Any = None
        self.cancel_requested = threading.Event()
        self.done = threading.Event()
        self._server = server
        self._waiters: list[PendingRequest] = []

    def publish_feedback(self, feedback: Any) -> None:
        s = self._server
        msg = s.node.types.message(f"{s.action_type}_FeedbackMessage",
                                   goal_id=_uuid(s.node, self.goal_id), feedback=feedback)
        s._feedback.publish(msg)

    def succeed(self, result: Any) -> None:
        self._server._finish(self, STATUS_SUCCEEDED, result)

    def abort(self, result: Any | None = None) -> None:
        self._server._finish(self, STATUS_ABORTED, result)

    def canceled(self, result: Any | None = None) -> None:
        self._server._finish(self, STATUS_CANCELED, result)


class ActionServer:
    """Serves action ``action_type`` (``pkg/action/Name``, registered in ``node.types``)
    as ``name``.

    ``on_goal(goal) -> bool`` accepts or rejects (default: accept); ``on_cancel(handle)
    -> bool`` grants a cancel request (default: grant); ``execute(handle)`` runs the goal.
    ``max_active`` goals may run at once (None: no limit); one more is rejected.
    """

    def __init__(self, node: Node, name: str, action_type: str,
                 execute: Callable[[GoalHandle], None], *,
                 on_goal: Callable[[Any], bool] | None = None,
                 on_cancel: Callable[[GoalHandle], bool] | None = None,
                 max_active: int | None = None, keep_results: int = 64) -> None:
        ensure_action_msgs(node)
        if node.types.kind(action_type) != "action":
            raise InvalidOption("action_type", action_type, "not an action type")
        self.node, self.name, self.action_type = node, node.resolve(name), action_type
        self._execute, self._on_goal, self._on_cancel = execute, on_goal, on_cancel
        self._keep, self._max_active = keep_results, max_active
        self._goals: OrderedDict[bytes, GoalHandle] = OrderedDict()
        self._lock = threading.RLock()
        self._threads: list[threading.Thread] = []
        n = action_endpoints(self.name)
        self._status = node.create_publisher(n["status"], GOAL_STATUS_ARRAY, qos=ACTION_STATUS)
        self._feedback = node.create_publisher(n["feedback"], f"{action_type}_FeedbackMessage")
        self._services = [
            node.create_service(n["send_goal"], f"{action_type}_SendGoal", self._send_goal),
            node.create_service(n["cancel_goal"], CANCEL_GOAL, self._cancel_goal),
            node.create_service(n["get_result"], f"{action_type}_GetResult", self._get_result,
                                deferred=True),
        ]
        self._closed = False

    # -- the three services -------------------------------------------------------------
    def _send_goal(self, request: Any, info: MessageInfo) -> Any:
        goal_id = bytes(request.goal_id.uuid)
        accepted, thread = False, None
        with self._lock:
            if goal_id in self._goals:
                log.warning("ROS2_GOAL_ID_IN_USE: %s rejects goal %s: its id is in use",
                            self.name, uuidlib.UUID(bytes=goal_id))
            elif self._closed:
                log.warning("%s rejects goal %s: the server is closing", self.name,
                            uuidlib.UUID(bytes=goal_id))
            elif self._max_active is not None and sum(
                    h.status not in TERMINAL for h in self._goals.values()) >= self._max_active:
                log.warning("ROS2_GOAL_BUSY: %s rejects goal %s: %d goal(s) already running",
                            self.name, uuidlib.UUID(bytes=goal_id), self._max_active)
            else:
                try:
                    accepted = bool(self._on_goal(request.goal)) if self._on_goal else True
                except Exception:
                    log.exception("%s: on_goal failed; goal rejected", self.name)
                if accepted:
                    handle = GoalHandle(self, goal_id, request.goal)
                    self._goals[goal_id] = handle
                    self._forget_old()
                    thread = threading.Thread(target=self._run, args=(handle,), daemon=True,
                                              name=f"action {self.name}")
                    self._threads.append(thread)
        if thread is not None:
            self._publish_status()
            thread.start()
        return self.node.types.message(f"{self.action_type}_SendGoal_Response",
                                       accepted=accepted,
                                       stamp=_stamp(self.node, time.time_ns()))

    def _cancel_goal(self, request: Any, info: MessageInfo) -> Any:
        goal_id = bytes(request.goal_info.goal_id.uuid)
        stamp = request.goal_info.stamp
        before = stamp.sec * 1_000_000_000 + stamp.nanosec
        every = goal_id == bytes(16)
        with self._lock:
            if every:
                targets = [h for h in self._goals.values()
                           if before == 0 or h.accepted_ns <= before]
            else:
                targets = [h for h in self._goals.values() if h.goal_id == goal_id
                           or (before and h.accepted_ns <= before)]
            code, canceling = ERROR_NONE, []
            if not every and goal_id not in self._goals:
                code = ERROR_UNKNOWN_GOAL_ID
            elif targets and all(h.status in TERMINAL for h in targets):
                code = ERROR_GOAL_TERMINATED
            else:
                for h in targets:
                    if h.status in TERMINAL:
                        continue
                    try:
                        granted = self._on_cancel(h) if self._on_cancel else True
                    except Exception:
                        log.exception("%s: on_cancel failed; cancel refused", self.name)
                        granted = False
                    if granted:
                        if h.status != STATUS_CANCELING:
                            h.status = STATUS_CANCELING
                            h.cancel_requested.set()
                        canceling.append(h)
                if not canceling:
                    code = ERROR_REJECTED
        if code != ERROR_NONE:
            log.info("ROS2_CANCEL_REFUSED: %s cancel of %s: code %d", self.name,
                     "every goal" if every else uuidlib.UUID(bytes=goal_id), code)
        else:
            self._publish_status()
        t = self.node.types
        infos = [t.message("action_msgs/msg/GoalInfo", goal_id=_uuid(self.node, h.goal_id),
                           stamp=_stamp(self.node, h.accepted_ns)) for h in canceling]
        return t.message(f"{CANCEL_GOAL}_Response", return_code=code, goals_canceling=infos)

    def _get_result(self, pending: PendingRequest) -> None:
        goal_id = bytes(pending.request.goal_id.uuid)
        with self._lock:
            handle = self._goals.get(goal_id)
            if handle is not None and handle.status not in TERMINAL:
                handle._waiters.append(pending)
                return
        if handle is None:
            log.info("ROS2_UNKNOWN_GOAL: %s has no goal %s for a result", self.name,
                     uuidlib.UUID(bytes=goal_id))
        pending.reply(self._result_response(handle))

    # -- goals --------------------------------------------------------------------------
    def _result_response(self, handle: GoalHandle | None) -> Any:
        t = self.node.types
        result = handle.result if handle is not None and handle.result is not None else \
            t.default(f"{self.action_type}_Result")
        return t.message(f"{self.action_type}_GetResult_Response",
                         status=STATUS_UNKNOWN if handle is None else handle.status,
                         result=result)

    def _run(self, handle: GoalHandle) -> None:
        with self._lock:
            if handle.status == STATUS_ACCEPTED:
                handle.status = STATUS_EXECUTING
        self._publish_status()
        try:
            self._execute(handle)
        except Exception:
            log.exception("%s: goal %s failed", self.name, uuidlib.UUID(bytes=handle.goal_id))
        if handle.status not in TERMINAL:
            log.warning("%s: goal %s ended without a result: aborted", self.name,
                        uuidlib.UUID(bytes=handle.goal_id))
            self._finish(handle, STATUS_ABORTED, None)

    def _finish(self, handle: GoalHandle, status: int, result: Any | None) -> None:
        with self._lock:
            if handle.status in TERMINAL:
                raise GoalAlreadyEnded(str(uuidlib.UUID(bytes=handle.goal_id)), handle.status)
            handle.status, handle.result = status, result
            waiters, handle._waiters = handle._waiters, []
        self._publish_status()
        response = self._result_response(handle)
        for w in waiters:
            w.reply(response)
        handle.done.set()

    def _forget_old(self) -> None:
        ended = [k for k, h in self._goals.items() if h.status in TERMINAL]
        for k in ended[:max(0, len(ended) - self._keep)]:
            del self._goals[k]

    def _publish_status(self) -> None:
        t = self.node.types
        with self._lock:
            statuses = [t.message("action_msgs/msg/GoalStatus",
                                  goal_info=t.message("action_msgs/msg/GoalInfo",
                                                      goal_id=_uuid(self.node, h.goal_id),
                                                      stamp=_stamp(self.node, h.accepted_ns)),
                                  status=h.status) for h in self._goals.values()]
        try:
            self._status.publish(t.message(GOAL_STATUS_ARRAY, status_list=statuses))
        except EntityClosed:
            # A goal that outlived close()'s wait ends after the topic is gone.
            log.debug("%s: status not published, the server is closed", self.name)

    def goals(self) -> list[GoalHandle]:
        with self._lock:
            return list(self._goals.values())

    def close(self, *, timeout: float = 5.0) -> None:
        """Ask every running goal to cancel, wait up to ``timeout`` [s] for them, then
        withdraw the services and topics."""
        with self._lock:
            self._closed = True
            for h in self._goals.values():
                if h.status not in TERMINAL:
                    h.cancel_requested.set()
            threads = list(self._threads)
        end = time.monotonic() + timeout
        for th in threads:
            if th.is_alive():
                th.join(max(0.0, end - time.monotonic()))
        self._threads = []
        for s in self._services:
            s.close()
        self._feedback.close()
        self._status.close()


@dataclass(frozen=True)
class GoalResult:
    """A goal's end: its status (``STATUS_SUCCEEDED`` ...) and result message."""

    status: int
    result: Any


class ActionClient:
    """Sends goals to action ``name`` of ``action_type`` and follows them.

    ``on_feedback(goal_id, feedback)`` runs on Zenoh's thread for each feedback message;
    :attr:`statuses` holds the last status seen per goal id.
    """

    def __init__(self, node: Node, name: str, action_type: str, *,
                 on_feedback: Callable[[bytes, Any], None] | None = None) -> None:
        ensure_action_msgs(node)
        self.node, self.name, self.action_type = node, node.resolve(name), action_type
        n = action_endpoints(self.name)
        self._send = node.create_client(n["send_goal"], f"{action_type}_SendGoal")
        self._cancel = node.create_client(n["cancel_goal"], CANCEL_GOAL)
        self._result = node.create_client(n["get_result"], f"{action_type}_GetResult")
        self.statuses: dict[bytes, int] = {}
        self._on_feedback = on_feedback
        self._fb = node.create_subscription(n["feedback"], f"{action_type}_FeedbackMessage",
                                            self._feedback)
        self._st = node.create_subscription(n["status"], GOAL_STATUS_ARRAY, self._status,
                                            qos=ACTION_STATUS)

    def _feedback(self, msg: Any, info: MessageInfo) -> None:
        if self._on_feedback is not None:
            self._on_feedback(bytes(msg.goal_id.uuid), msg.feedback)

    def _status(self, msg: Any, info: MessageInfo) -> None:
        for s in msg.status_list:
            self.statuses[bytes(s.goal_info.goal_id.uuid)] = int(s.status)

    def wait_for_server(self, timeout: float) -> bool:
        """Whether the action's three services announce themselves within ``timeout`` [s]
        (as ``rclcpp_action::Client::wait_for_action_server``)."""
        end = time.monotonic() + timeout
        return all(c.wait_for_server(max(0.0, end - time.monotonic()))
                   for c in (self._send, self._cancel, self._result))

    def send_goal(self, goal: Any, *, goal_id: bytes | None = None,
                  timeout: float = 5.0) -> tuple[bytes, bool]:
        """Send ``goal`` (a ``<Action>_Goal``); returns (goal id, accepted)."""
        gid = uuidlib.uuid4().bytes if goal_id is None else goal_id
        req = self.node.types.message(f"{self.action_type}_SendGoal_Request",
                                      goal_id=_uuid(self.node, gid), goal=goal)
        return gid, bool(self._send.call(req, timeout=timeout).accepted)

    def get_result(self, goal_id: bytes, *, timeout: float = 60.0) -> GoalResult:
        """Wait up to ``timeout`` [s] for the goal's end."""
        req = self.node.types.message(f"{self.action_type}_GetResult_Request",
                                      goal_id=_uuid(self.node, goal_id))
        res = self._result.call(req, timeout=timeout)
        return GoalResult(int(res.status), res.result)

    def cancel(self, goal_id: bytes | None = None, *, before_ns: int = 0,
               timeout: float = 5.0) -> tuple[int, list[bytes]]:
        """Cancel ``goal_id`` (every goal if None, those accepted by ``before_ns``);
        returns (return code, ids of the goals now canceling)."""
        t = self.node.types
        info = t.message("action_msgs/msg/GoalInfo",
                         goal_id=_uuid(self.node, goal_id or bytes(16)),
                         stamp=_stamp(self.node, before_ns))
        res = self._cancel.call(t.message(f"{CANCEL_GOAL}_Request", goal_info=info),
                                timeout=timeout)
        return int(res.return_code), [bytes(g.goal_id.uuid) for g in res.goals_canceling]

    def close(self) -> None:
        for e in (self._send, self._cancel, self._result, self._fb, self._st):
            e.close()
