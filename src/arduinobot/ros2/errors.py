"""Every way the ROS 2 wire layer can fail, one exception class each, under :class:`Ros2Error`.

``code`` names the failure for logs; none of these codes is sent on the service's JSON
keys (the ROS 2 side is a separate front door, and its failures stay on it).
"""

from __future__ import annotations

from collections.abc import Mapping


class Ros2Error(Exception):
    """Root of every ROS 2 wire error. ``details`` says what a user needs to act."""

    code: str = "ROS2_ERROR"

    def __init__(self, message: str, *, details: Mapping[str, object] | None = None) -> None:
        self.message = message
        self.details = dict(details or {})
        super().__init__(f"[{self.code}] {message}")


class InvalidName(Ros2Error):
    """A node name, namespace, topic or service name breaks the ROS 2 naming rules."""

    code = "ROS2_INVALID_NAME"

    def __init__(self, name: str, reason: str, *, kind: str) -> None:
        self.name, self.reason, self.kind = name, reason, kind
        super().__init__(f"{kind} {name!r}: {reason}",
                         details={"name": name, "kind": kind, "reason": reason})


class InvalidOption(Ros2Error):
    """An option out of its range: a domain id, an attachment layout, joint names."""

    code = "ROS2_INVALID_OPTION"

    def __init__(self, option: str, value: object, reason: str) -> None:
        self.option, self.value, self.reason = option, value, reason
        super().__init__(f"{option} = {value!r}: {reason}",
                         details={"option": option, "value": repr(value), "reason": reason})


class UnknownType(Ros2Error):
    """A message, service or action type that the type store does not hold."""

    code = "ROS2_UNKNOWN_TYPE"

    def __init__(self, type_name: str, *, hint: str = "") -> None:
        self.type_name = type_name
        super().__init__(f"unknown type {type_name!r}" + (f": {hint}" if hint else ""),
                         details={"type": type_name})


class InvalidTypeDefinition(Ros2Error):
    """A .msg/.srv/.action text that cannot be parsed or registered."""

    code = "ROS2_INVALID_TYPE_DEFINITION"

    def __init__(self, type_name: str, reason: str) -> None:
        self.type_name, self.reason = type_name, reason
        super().__init__(f"{type_name}: {reason}", details={"type": type_name,
                                                           "reason": reason})


class MalformedCdr(Ros2Error):
    """Bytes that do not decode as CDR of the expected type (truncated, wrong type, junk)."""

    code = "ROS2_MALFORMED_CDR"

    def __init__(self, type_name: str, reason: str, *, size: int) -> None:
        self.type_name, self.reason, self.size = type_name, reason, size
        super().__init__(f"{size} bytes are not a CDR {type_name}: {reason}",
                         details={"type": type_name, "size": size, "reason": reason})


class MessageMismatch(Ros2Error):
    """A message object whose fields do not fit its type, so it cannot be serialised."""

    code = "ROS2_MESSAGE_MISMATCH"

    def __init__(self, type_name: str, reason: str) -> None:
        self.type_name, self.reason = type_name, reason
        super().__init__(f"cannot serialise a {type_name}: {reason}",
                         details={"type": type_name, "reason": reason})


class MalformedAttachment(Ros2Error):
    """A put, query or reply whose attachment is missing or not in the expected layout."""

    code = "ROS2_MALFORMED_ATTACHMENT"

    def __init__(self, reason: str, *, layout: str, size: int | None) -> None:
        self.reason, self.layout, self.size = reason, layout, size
        super().__init__(f"attachment ({layout} layout, "
                         f"{'none' if size is None else f'{size} bytes'}): {reason}",
                         details={"layout": layout, "size": size, "reason": reason})


class MalformedToken(Ros2Error):
    """A liveliness key expression that is not an rmw_zenoh graph token."""

    code = "ROS2_MALFORMED_TOKEN"

    def __init__(self, key: str, reason: str) -> None:
        self.key, self.reason = key, reason
        super().__init__(f"{key!r}: {reason}", details={"key": key, "reason": reason})


class ServiceFailed(Ros2Error):
    """A service call got no usable reply: no server, a timeout, or an error reply."""

    code = "ROS2_SERVICE_FAILED"

    def __init__(self, service: str, reason: str) -> None:
        self.service, self.reason = service, reason
        super().__init__(f"{service}: {reason}", details={"service": service,
                                                         "reason": reason})


class GoalAlreadyEnded(Ros2Error):
    """An action goal ended twice (an ``execute`` that calls succeed/abort/canceled again)."""

    code = "ROS2_GOAL_ENDED"

    def __init__(self, goal_id: str, status: int) -> None:
        self.goal_id, self.status = goal_id, status
        super().__init__(f"goal {goal_id} already ended (status {status})",
                         details={"goal_id": goal_id, "status": status})


class EntityClosed(Ros2Error):
    """A publisher, client or node used after ``close()``."""

    code = "ROS2_CLOSED"

    def __init__(self, what: str) -> None:
        super().__init__(f"{what} is closed", details={"entity": what})


class NoController(Ros2Error):
    """Joints of a trajectory that no controller moves (or that two claim)."""

    code = "ROS2_NO_CONTROLLER"

    def __init__(self, joints: list[str], reason: str, *, controllers: list[str]) -> None:
        self.joints, self.controllers = joints, controllers
        super().__init__(f"{', '.join(joints)}: {reason} (controllers: "
                         f"{', '.join(controllers) or 'none'})",
                         details={"joints": joints, "controllers": controllers})


class ControllerUnavailable(Ros2Error):
    """A controller's action server or trajectory subscription did not show up."""

    code = "ROS2_CONTROLLER_UNAVAILABLE"

    def __init__(self, controller: str, name: str, timeout: float) -> None:
        self.controller, self.name = controller, name
        super().__init__(f"{controller}: nothing serves {name} (waited {timeout:g} s): is "
                         "the controller active, on this domain, behind the same router?",
                         details={"controller": controller, "name": name, "timeout": timeout})


class GoalRejected(Ros2Error):
    """A controller refused the goal (joint_trajectory_controller: joints it lacks, an
    empty or invalid trajectory, the controller inactive)."""

    code = "ROS2_GOAL_REJECTED"

    def __init__(self, controller: str) -> None:
        self.controller = controller
        super().__init__(f"{controller} rejected the goal (see the controller's log: its "
                         "joints, the trajectory, the controller active?)",
                         details={"controller": controller})


class ControllerFailed(Ros2Error):
    """A goal that ended other than succeeded, or with ``error_code != 0``; ``details``
    hold the controller's ``error_code`` (its name too) and ``error_string``."""

    code = "ROS2_CONTROLLER_FAILED"

    def __init__(self, controller: str, reason: str, error_code: int | None,
                 error_string: str, *, error_name: str | None = None) -> None:
        self.controller, self.error_code, self.error_string = controller, error_code, error_string
        shown = "" if error_code is None else \
            f": error_code {error_code}" + (f" ({error_name})" if error_name else "")
        super().__init__(f"{controller} {reason}{shown}"
                         + (f": {error_string}" if error_string else ""),
                         details={"controller": controller, "error_code": error_code,
                                  "error_name": error_name, "error_string": error_string})


class UnknownFrame(Ros2Error):
    """A message's ``header.frame_id`` that names no link of the model: its data cannot
    be placed in the world (a point cloud, a camera image)."""

    code = "ROS2_UNKNOWN_FRAME"

    def __init__(self, topic: str, frame_id: str, *, robot: str, links: list[str]) -> None:
        self.topic, self.frame_id = topic, frame_id
        shown = ", ".join(links[:12]) + (", ..." if len(links) > 12 else "")
        super().__init__(f"{topic}: frame_id {frame_id!r} is not a link of robot {robot!r} "
                         f"(its links: {shown}); publish in the camera's link, or add the "
                         "camera to the model on a fixed joint",
                         details={"topic": topic, "frame_id": frame_id, "links": links})
