"""Run a trajectory on a ros2_control stack: one ``joint_trajectory_controller`` per group.

Each :class:`arduinobot.ros2.controllers.Part` goes to its controller as a
``control_msgs/action/FollowJointTrajectory`` goal on ``/<controller>/<action_ns>``
(:meth:`TrajectoryTarget.follow`, feedback and result followed; a rejected goal or an
``error_code != 0`` is a coded :class:`ControllerFailed` with the controller's
``error_string``), or as a plain ``trajectory_msgs/msg/JointTrajectory`` on
``/<controller>/joint_trajectory`` (:meth:`TrajectoryTarget.publish`; no result exists on
that interface), from a node of the target's own on the rmw_zenoh wire.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from arduinobot.ros2.actions import (
    STATUS_CANCELED,
    STATUS_SUCCEEDED,
    ActionClient,
    action_endpoints,
)
from arduinobot.ros2.control_msgs import (
    CONTROL_MSGS,
    ERROR_CODES,
    FOLLOW_JOINT_TRAJECTORY,
    ControlMsgs,
    control_msgs_types,
)
from arduinobot.ros2.controllers import JOINT_TRAJECTORY, Controller, Part, joint_trajectory
from arduinobot.ros2.errors import (
    ControllerFailed,
    ControllerUnavailable,
    GoalRejected,
    InvalidOption,
)
from arduinobot.ros2.wire.graph import endpoint_selector, query_graph
from arduinobot.ros2.wire.node import Node

if TYPE_CHECKING:
    import zenoh

    from arduinobot.ros2.attachment import AttachmentLayout

log = logging.getLogger(__name__)

#: an action's final status, as a failure names it
_STATUS = {STATUS_SUCCEEDED: "succeeded", STATUS_CANCELED: "canceled", 6: "aborted",
           0: "with an unknown status"}


@dataclass(frozen=True)
class Feedback:
    """One controller's feedback: its joints, the desired and actual positions [rad]."""

    controller: str
    joint_names: tuple[str, ...]
    desired: tuple[float, ...]
    actual: tuple[float, ...]


@dataclass(frozen=True)
class PartOutcome:
    """How one controller's goal ended: ``"succeeded"`` or ``"cancelled"`` (failures
    raise), its ``error_code`` and ``error_string``."""

    controller: str
    outcome: Literal["succeeded", "cancelled"]
    error_code: int = 0
    error_string: str = ""


@dataclass(frozen=True)
class TargetOptions:
    """``server_timeout`` [s]: how long a controller may take to show up;
    ``result_slack`` [s]: how long past the trajectory's end a result may take."""

    server_timeout: float = 5.0
    result_slack: float = 10.0
    control_msgs: ControlMsgs = "auto"
    node_name: str = "arduinobot_execute"


def detect_control_msgs(session: zenoh.Session, controller: Controller, *, domain_id: int,
                        namespace: str = "/", timeout: float = 2.0
                        ) -> Literal["jazzy", "rolling"] | None:
    """Which control_msgs the controller's feedback publisher announces (its liveliness
    token's type hash), or None when it announces none we know."""
    from arduinobot.ros2.wire.names import fully_qualified
    name = action_endpoints(fully_qualified(controller.action, namespace))["feedback"]
    for version in ("jazzy", "rolling"):
        types = control_msgs_types(version)
        fb = f"{FOLLOW_JOINT_TRAJECTORY}_FeedbackMessage"
        sel = endpoint_selector(domain_id, "MP", name, types.dds_name(fb), types.type_hash(fb))
        if query_graph(session, sel, timeout=timeout):
            return version
    return None


class TrajectoryTarget:
    """Sends trajectories to joint_trajectory_controllers from a node of its own on
    ``session``. ``close()`` withdraws the node."""

    def __init__(self, session: zenoh.Session, *, domain_id: int = 0, namespace: str = "/",
                 attachment: AttachmentLayout = "current",
                 options: TargetOptions | None = None) -> None:
        self.session, self.domain_id, self.namespace = session, domain_id, namespace
        self.attachment: AttachmentLayout = attachment
        self.options = options or TargetOptions()
        if self.options.control_msgs not in CONTROL_MSGS:
            raise InvalidOption("control_msgs", self.options.control_msgs,
                                f"one of {CONTROL_MSGS}")
        self._nodes: dict[str, Node] = {}

    def _node(self, version: str) -> Node:
        if version not in self._nodes:
            suffix = "" if not self._nodes else f"_{len(self._nodes)}"
            self._nodes[version] = Node(self.session, self.options.node_name + suffix,
                                        namespace=self.namespace, domain_id=self.domain_id,
                                        types=control_msgs_types(version),  # type: ignore[arg-type]
                                        attachment=self.attachment)
        return self._nodes[version]

    def _version(self, controller: Controller) -> str:
        v = self.options.control_msgs
        if v != "auto":
            return v
        found = detect_control_msgs(self.session, controller, domain_id=self.domain_id,
                                    namespace=self.namespace, timeout=1.0)
        if found is None:
            log.info("%s announces no feedback type we know: assuming Jazzy's control_msgs "
                     "(feedback may not arrive)", controller.name)
        return found or "jazzy"

    # -- the action -----------------------------------------------------------------------
    def follow(self, parts: Sequence[Part], *, cancel: threading.Event | None = None,
               on_feedback: Callable[[Feedback], None] | None = None
               ) -> list[PartOutcome]:
        """Send each part to its controller's FollowJointTrajectory action (all goals out
        before any wait, so the controllers start together), then wait for every result.
        ``cancel`` set: every goal still running is cancelled (the controllers stop and
        hold); those parts end ``"cancelled"``.

        Raises:
            ControllerUnavailable: a controller's action server does not show up.
            ControllerFailed: a goal rejected, or a result with ``error_code != 0`` or
                not succeeded (the first such; the other goals are cancelled first).
        """
        cancel = cancel or threading.Event()
        clients: list[tuple[Part, ActionClient, bytes]] = []
        try:
            for part in parts:
                node = self._node(self._version(part.controller))
                c = part.controller

                def feedback(gid: bytes, fb: Any, name: str = c.name) -> None:
                    if on_feedback is not None:
                        on_feedback(Feedback(name, tuple(fb.joint_names),
                                             tuple(float(x) for x in fb.desired.positions),
                                             tuple(float(x) for x in fb.actual.positions)))
                client = ActionClient(node, c.action, FOLLOW_JOINT_TRAJECTORY,
                                      on_feedback=feedback)
                clients.append((part, client, b""))
                if not client.wait_for_server(self.options.server_timeout):
                    raise ControllerUnavailable(c.name, node.resolve(c.action),
                                                self.options.server_timeout)
            for i, (part, client, _) in enumerate(clients):
                goal = client.node.types.message(
                    f"{FOLLOW_JOINT_TRAJECTORY}_Goal", **self._goal_fields(client.node, part))
                gid, accepted = client.send_goal(goal, timeout=self.options.server_timeout)
                if not accepted:
                    self._cancel_all(clients[:i])
                    raise GoalRejected(part.controller.name)
                clients[i] = (part, client, gid)
            return self._wait(clients, cancel)
        finally:
            for _, client, _ in clients:
                client.close()

    def _goal_fields(self, node: Node, part: Part) -> dict[str, Any]:
        t = node.types
        return {"trajectory": joint_trajectory(t, part),
                "multi_dof_trajectory": t.default("trajectory_msgs/msg/MultiDOFJointTrajectory"),
                "path_tolerance": [], "component_path_tolerance": [], "goal_tolerance": [],
                "component_goal_tolerance": [],
                "goal_time_tolerance": t.message("builtin_interfaces/msg/Duration", sec=0,
                                                 nanosec=0)}

    def _wait(self, clients: list[tuple[Part, ActionClient, bytes]],
              cancel: threading.Event) -> list[PartOutcome]:
        results: dict[int, Any] = {}
        errors: dict[int, BaseException] = {}
        timeout = max(p.duration for p, _, _ in clients) + self.options.result_slack

        def wait(i: int, client: ActionClient, gid: bytes) -> None:
            try:
                results[i] = client.get_result(gid, timeout=timeout)
            except BaseException as e:  # noqa: BLE001 -- handed to the caller's thread
                errors[i] = e
        threads = [threading.Thread(target=wait, args=(i, c, g), daemon=True,
                                    name=f"result {p.controller.name}")
                   for i, (p, c, g) in enumerate(clients)]
        for th in threads:
            th.start()
        stopping = False  # cancels sent (asked for, or one controller failed)
        first_failure: int | None = None
        while any(th.is_alive() for th in threads):
            if first_failure is None:
                first_failure = next((i for i, r in sorted(results.items())
                                      if self._failed(r)), None)
                if first_failure is None and errors:
                    first_failure = min(errors)
            if not stopping and (cancel.is_set() or first_failure is not None):
                stopping = True  # one failed: stop the others too, as MoveIt does
                self._cancel_all([x for i, x in enumerate(clients) if i not in results])
            time.sleep(0.02)
        if first_failure is None:
            # a goal cancelled that we did not cancel (preempted by another client) failed
            first_failure = next((i for i in range(len(clients))
                                  if i in errors or self._failed(results[i])
                                  or (results[i].status == STATUS_CANCELED and not stopping)),
                                 None)
        if first_failure is not None:
            name = clients[first_failure][0].controller.name
            if first_failure in errors:
                raise ControllerFailed(name, f"gave no result: {errors[first_failure]}",
                                       None, "")
            r = results[first_failure]
            code = int(r.result.error_code)
            raise ControllerFailed(name, f"ended the goal {_STATUS.get(r.status, r.status)}",
                                   code, str(r.result.error_string),
                                   error_name=ERROR_CODES.get(code))
        return [PartOutcome(p.controller.name,
                            "succeeded" if results[i].status == STATUS_SUCCEEDED else
                            "cancelled", int(results[i].result.error_code),
                            str(results[i].result.error_string))
                for i, (p, _, _) in enumerate(clients)]

    @staticmethod
    def _failed(r: Any) -> bool:
        """A result other than success (a cancel we asked for is sorted out later)."""
        return r.status != STATUS_SUCCEEDED and r.status != STATUS_CANCELED \
            or int(r.result.error_code) != 0

    @staticmethod
    def _cancel_all(clients: Sequence[tuple[Part, ActionClient, bytes]]) -> None:
        for part, client, gid in clients:
            if not gid:
                continue
            try:
                code, _ = client.cancel(gid)
                log.info("%s: cancel requested (return code %d)", part.controller.name, code)
            except Exception as e:  # noqa: BLE001 -- the others are cancelled all the same
                log.warning("%s: cancel failed: %s", part.controller.name, e)

    # -- the topic --------------------------------------------------------------------------
    def publish(self, parts: Sequence[Part], *, cancel: threading.Event | None = None,
                wait: bool = True) -> bool:
        """Publish each part on ``/<controller>/joint_trajectory`` (once the controller's
        subscription shows up); with ``wait``, sleep through the longest part. ``cancel``
        set meanwhile: an empty trajectory goes to each (joint_trajectory_controller then
        holds position). Returns False when cancelled.

        Raises:
            ControllerUnavailable: a controller does not subscribe within the timeout.
        """
        cancel = cancel or threading.Event()
        node = self._node("jazzy")
        pubs = []
        try:
            for part in parts:
                c = part.controller
                pub = node.create_publisher(c.topic, JOINT_TRAJECTORY)
                pubs.append((part, pub))
                sel = endpoint_selector(self.domain_id, "MS", node.resolve(c.topic),
                                        node.types.dds_name(JOINT_TRAJECTORY),
                                        node.types.type_hash(JOINT_TRAJECTORY))
                end = time.monotonic() + self.options.server_timeout
                while not query_graph(self.session, sel, timeout=0.5):
                    if time.monotonic() > end:
                        raise ControllerUnavailable(c.name, node.resolve(c.topic),
                                                    self.options.server_timeout)
                    time.sleep(0.05)
            for part, pub in pubs:
                pub.publish(joint_trajectory(node.types, part))
            if not wait:
                return True
            if cancel.wait(max(p.duration for p in parts)):
                for part, pub in pubs:
                    empty = Part(part.controller, part.joint_names, np.zeros(0),
                                 np.zeros((0, len(part.joint_names))), None, None)
                    pub.publish(joint_trajectory(node.types, empty))
                return False
            return True
        finally:
            for _, pub in pubs:
                pub.close()

    # -- where the robot is ------------------------------------------------------------------
    def joint_positions(self, *, timeout: float = 3.0, topic: str = "joint_states"
                        ) -> dict[str, float] | None:
        """The positions [rad] of the first ``sensor_msgs/msg/JointState`` on ``topic``
        (ros2_control's joint_state_broadcaster publishes it), or None if none arrives
        within ``timeout`` [s]."""
        got: list[dict[str, float]] = []
        done = threading.Event()

        def on_msg(msg: Any, info: Any) -> None:
            if not done.is_set() and len(msg.name) == len(msg.position):
                got.append({str(n): float(p) for n, p in zip(msg.name, msg.position)})
                done.set()
        sub = self._node("jazzy").create_subscription(topic, "sensor_msgs/msg/JointState",
                                                      on_msg)
        try:
            done.wait(timeout)
        finally:
            sub.close()
        return got[0] if got else None

    def close(self) -> None:
        for node in self._nodes.values():
            node.close()
        self._nodes.clear()
