"""Run a trajectory on a ros2_control stack: one ``joint_trajectory_controller`` per group.

What MoveIt's ``moveit_simple_controller_manager`` does, on the rmw_zenoh wire:
``moveit_controllers.yaml`` names the controllers and their joints
(:func:`read_moveit_controllers`), a trajectory is split per controller
(:func:`split_trajectory`), and each part goes to its controller as a
``control_msgs/action/FollowJointTrajectory`` goal on ``/<controller>/<action_ns>``
(:class:`TrajectoryTarget`, feedback and result followed; a rejected goal or an
``error_code != 0`` is a coded :class:`ControllerFailed` with the controller's
``error_string``), or as a plain ``trajectory_msgs/msg/JointTrajectory`` on
``/<controller>/joint_trajectory`` (``topic=True``; no result exists on that interface).

control_msgs is not in rosbags' stores: its types are registered here from the upstream
``.msg``/``.action`` text (github.com/ros-controls/control_msgs, control_msgs/msg/
JointTolerance.msg, JointComponentTolerance.msg, action/FollowJointTrajectory.action):
branch ``jazzy`` @ f901df2662f22a39a06aa04a85a34602c47e3cc0 (release 5.8.0, what Jazzy
ships) and ``master`` @ 13dacdd8748264b6cd7cbbc9893c18c90e24be00 (6.8.0; since 6.3.0 the
feedback carries ``index`` and ``multi_dof_index``, commit b0f5dfc). The two differ in the
feedback only: the goal and result (so send_goal and get_result, and their type hashes)
are the same, so a wrong choice costs the feedback, never the motion; ``"auto"`` picks the
one whose feedback type hash the controller announces. Nothing here imports ``clients/``,
``service/`` or ``execution/``: the caller hands plain arrays.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from .actions import (
    STATUS_CANCELED,
    STATUS_SUCCEEDED,
    ActionClient,
    action_endpoints,
)
from .errors import (
    ControllerFailed,
    ControllerUnavailable,
    GoalRejected,
    InvalidOption,
    NoController,
)
from .graph import endpoint_selector, query_graph
from .node import Node
from .types import TypeStore

if TYPE_CHECKING:
    import zenoh

    from .attachment import AttachmentLayout

log = logging.getLogger(__name__)

FOLLOW_JOINT_TRAJECTORY = "control_msgs/action/FollowJointTrajectory"
JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
ControlMsgs = Literal["auto", "jazzy", "rolling"]
CONTROL_MSGS: tuple[str, ...] = ("auto", "jazzy", "rolling")

# control_msgs/msg/JointTolerance.msg; comments dropped and, in the .action, the package
# named on JointTolerance and JointComponentTolerance (the parser resolves a bare name
# in the .action's own namespace): neither changes the type or its hash
JOINT_TOLERANCE = "string name\nfloat64 position\nfloat64 velocity\nfloat64 acceleration\n"
# control_msgs/msg/JointComponentTolerance.msg
JOINT_COMPONENT_TOLERANCE = """uint16 X_AXIS=1
uint16 Y_AXIS=2
uint16 Z_AXIS=3
uint16 TRANSLATION=4
uint16 ROTATION=5
string joint_name
uint16 component
float64 position
float64 velocity
float64 acceleration
"""
_GOAL = """trajectory_msgs/JointTrajectory trajectory
trajectory_msgs/MultiDOFJointTrajectory multi_dof_trajectory
control_msgs/JointTolerance[] path_tolerance
control_msgs/JointComponentTolerance[] component_path_tolerance
control_msgs/JointTolerance[] goal_tolerance
control_msgs/JointComponentTolerance[] component_goal_tolerance
builtin_interfaces/Duration goal_time_tolerance
"""
_RESULT = """int32 error_code
int32 SUCCESSFUL = 0
int32 INVALID_GOAL = -1
int32 INVALID_JOINTS = -2
int32 OLD_HEADER_TIMESTAMP = -3
int32 PATH_TOLERANCE_VIOLATED = -4
int32 GOAL_TOLERANCE_VIOLATED = -5
string error_string
"""
_FEEDBACK_JAZZY = """std_msgs/Header header
string[] joint_names
trajectory_msgs/JointTrajectoryPoint desired
trajectory_msgs/JointTrajectoryPoint actual
trajectory_msgs/JointTrajectoryPoint error
string[] multi_dof_joint_names
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error
"""
_FEEDBACK_ROLLING = """std_msgs/Header header
string[] joint_names
trajectory_msgs/JointTrajectoryPoint desired
trajectory_msgs/JointTrajectoryPoint actual
trajectory_msgs/JointTrajectoryPoint error
int32 index
string[] multi_dof_joint_names
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error
int32 multi_dof_index
"""
FOLLOW_JOINT_TRAJECTORY_ACTION: Mapping[str, str] = {
    v: f"{_GOAL}---\n{_RESULT}---\n{fb}"
    for v, fb in (("jazzy", _FEEDBACK_JAZZY), ("rolling", _FEEDBACK_ROLLING))}
#: FollowJointTrajectory_Result.error_code names (the .action's constants)
_STATUS = {STATUS_SUCCEEDED: "succeeded", STATUS_CANCELED: "canceled", 6: "aborted",
           0: "with an unknown status"}
ERROR_CODES: Mapping[int, str] = {0: "SUCCESSFUL", -1: "INVALID_GOAL", -2: "INVALID_JOINTS",
                                  -3: "OLD_HEADER_TIMESTAMP", -4: "PATH_TOLERANCE_VIOLATED",
                                  -5: "GOAL_TOLERANCE_VIOLATED"}


def control_msgs_types(version: Literal["jazzy", "rolling"] = "jazzy") -> TypeStore:
    """A type store with control_msgs' FollowJointTrajectory (and its tolerances) of
    ``version`` registered."""
    if version not in FOLLOW_JOINT_TRAJECTORY_ACTION:
        raise InvalidOption("control_msgs", version, "jazzy or rolling")
    types = TypeStore()
    types.register_msg("control_msgs/msg/JointTolerance", JOINT_TOLERANCE)
    types.register_msg("control_msgs/msg/JointComponentTolerance", JOINT_COMPONENT_TOLERANCE)
    types.register_action(FOLLOW_JOINT_TRAJECTORY, FOLLOW_JOINT_TRAJECTORY_ACTION[version])
    return types


# -- which controller moves which joints ----------------------------------------------------

@dataclass(frozen=True)
class Controller:
    """A controller MoveIt knows: its ``name`` (``/<name>/...``), its joints, and the
    action's namespace under it (``/<name>/<action_ns>``)."""

    name: str
    joints: tuple[str, ...]
    action_ns: str = "follow_joint_trajectory"

    @property
    def action(self) -> str:
        return f"{self.name}/{self.action_ns}"

    @property
    def topic(self) -> str:
        return f"{self.name}/joint_trajectory"


def read_moveit_controllers(path: str | Path) -> tuple[Controller, ...]:
    """The FollowJointTrajectory controllers of a MoveIt ``moveit_controllers.yaml``
    (``moveit_simple_controller_manager.controller_names`` and, per name, ``joints`` and
    ``action_ns``), in the file's order. A controller of another type (a
    GripperCommand) is skipped with a warning.

    Raises:
        InvalidOption: the file is unreadable or not in that shape (naming what is wrong).
    """
    import yaml

    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as e:
        raise InvalidOption("moveit_controllers.yaml", str(p), f"unreadable: {e}") from e
    manager = data.get("moveit_simple_controller_manager") if isinstance(data, dict) else None
    names = manager.get("controller_names") if isinstance(manager, dict) else None
    if not isinstance(manager, dict) or not isinstance(names, list) \
            or not all(isinstance(n, str) for n in names):
        raise InvalidOption("moveit_controllers.yaml", str(p), "no moveit_simple_controller_"
                            "manager.controller_names list")
    out = []
    for name in names:
        entry = manager.get(name)
        if not isinstance(entry, dict) or not isinstance(entry.get("joints"), list):
            raise InvalidOption("moveit_controllers.yaml", str(p),
                                f"controller {name} has no joints list")
        kind = entry.get("type", "FollowJointTrajectory")
        if kind != "FollowJointTrajectory":
            log.warning("%s: controller %s is a %s, not a FollowJointTrajectory: skipped",
                        p, name, kind)
            continue
        out.append(Controller(name, tuple(str(j) for j in entry["joints"]),
                              str(entry.get("action_ns") or "follow_joint_trajectory")))
    return tuple(out)


@dataclass(frozen=True)
class Part:
    """The piece of a trajectory one controller plays: ``joint_names`` (the trajectory's
    order), ``times`` (m,) [s] and ``positions``/``velocities``/``accelerations`` (m, k),
    the last two None where the plan has none."""

    controller: Controller
    joint_names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None

    @property
    def duration(self) -> float:
        return float(self.times[-1])


def split_trajectory(joint_names: Sequence[str], times: Sequence[float] | np.ndarray,
                     columns: Mapping[str, np.ndarray], controllers: Sequence[Controller]
                     ) -> list[Part]:
    """The trajectory (``columns``: ``positions`` and optionally ``velocities``,
    ``accelerations``, each (m, dof), NaN rows where a point lacks one) cut per
    controller; controllers that own none of its joints get nothing.

    Raises:
        NoController: a joint no controller owns, or one two controllers claim.
    """
    owner: dict[str, Controller] = {}
    for c in controllers:
        for j in c.joints:
            if j in owner and j in joint_names:
                raise NoController([j], f"both {owner[j].name} and {c.name} claim it",
                                   controllers=[x.name for x in controllers])
            owner.setdefault(j, c)
    orphans = [j for j in joint_names if j not in owner]
    if orphans:
        raise NoController(orphans, "no controller moves them",
                           controllers=[c.name for c in controllers])
    t = np.asarray(times, float)
    parts = []
    for c in controllers:
        idx = [i for i, j in enumerate(joint_names) if owner[j] is c]
        if not idx:
            continue
        missing = [j for j in c.joints if j not in joint_names]
        if missing:
            log.warning("%s also has %s, which the trajectory does not move: the controller "
                        "rejects the goal unless allow_partial_joints_goal is set",
                        c.name, ", ".join(missing))
        positions = _cut(columns, "positions", idx)
        if positions is None:
            raise InvalidOption("trajectory", "positions", "every point needs positions")
        parts.append(Part(c, tuple(joint_names[i] for i in idx), t, positions,
                          _cut(columns, "velocities", idx),
                          _cut(columns, "accelerations", idx)))
    return parts


def _cut(columns: Mapping[str, np.ndarray], key: str, idx: list[int]) -> np.ndarray | None:
    col = columns.get(key)
    if col is None:
        return None
    sub = np.asarray(col, float)[:, idx]
    return None if np.isnan(sub).all() else sub


def joint_trajectory(types: TypeStore, part: Part, *, stamp_ns: int = 0) -> Any:
    """The ``trajectory_msgs/msg/JointTrajectory`` of ``part``; stamp 0 (the default)
    means "start on receipt" to joint_trajectory_controller."""
    def row(a: np.ndarray | None, k: int) -> np.ndarray:
        if a is None or np.isnan(a[k]).any():
            return np.zeros(0)
        return np.ascontiguousarray(a[k], dtype=np.float64)

    points = []
    for k, t in enumerate(part.times):
        ns = round(float(t) * 1e9)
        points.append(types.message(
            "trajectory_msgs/msg/JointTrajectoryPoint", positions=row(part.positions, k),
            velocities=row(part.velocities, k), accelerations=row(part.accelerations, k),
            effort=np.zeros(0),
            time_from_start=types.message("builtin_interfaces/msg/Duration",
                                          sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
    stamp = types.message("builtin_interfaces/msg/Time", sec=stamp_ns // 1_000_000_000,
                          nanosec=stamp_ns % 1_000_000_000)
    return types.message(JOINT_TRAJECTORY,
                         header=types.message("std_msgs/msg/Header", stamp=stamp, frame_id=""),
                         joint_names=list(part.joint_names), points=points)


# -- the target -------------------------------------------------------------------------------

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
    from .names import fully_qualified
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
