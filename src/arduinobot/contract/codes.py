"""Every error code either service puts on the wire, in one place.

The planner's exceptions (:mod:`arduinobot.contract.errors`), the planning service's replies
(``src/arduinobot/service/``), its schema (``src/arduinobot/contract/schema/error.json``), the client's exceptions
(:mod:`arduinobot.client.errors`) and execution's (``src/arduinobot/service/execute/execution.py``, ``src/arduinobot/execution/``
with its drivers) all take their codes from :class:`Code`; ``tests/contract/test_codes.py`` fails
if any of them uses a code not listed here, or if the schema's enum drifts from
:data:`PLAN_SERVICE_CODES`. It lives in ``src/arduinobot/planner/``, the lowest layer, so every layer
can import it.
"""

from __future__ import annotations

from enum import Enum


class Code(str, Enum):
    """A wire error code. A ``str``: it compares equal to, formats, prints and
    JSON-encodes as its plain string, so replies and client lookups need no conversion.
    (``enum.StrEnum`` would do the same but needs Python 3.11.)"""

    __str__ = str.__str__

    def __format__(self, spec: str) -> str:
        return str.__format__(self, spec)

    # the planning service's replies (src/arduinobot/contract/schema/error.json)
    INVALID_REQUEST = "INVALID_REQUEST"
    START_IN_COLLISION = "START_IN_COLLISION"
    GOAL_IN_COLLISION = "GOAL_IN_COLLISION"
    GOAL_OUT_OF_REACH = "GOAL_OUT_OF_REACH"
    NO_PATH_FOUND = "NO_PATH_FOUND"
    TRAJECTORY_FAILED = "TRAJECTORY_FAILED"
    INVALID_LIMITS = "INVALID_LIMITS"
    LINE_INTERRUPTED = "LINE_INTERRUPTED"
    ORIENTATION_NOT_CONTROLLABLE = "ORIENTATION_NOT_CONTROLLABLE"
    TIMEOUT = "TIMEOUT"
    BUSY = "BUSY"
    RESOURCE_LIMIT = "RESOURCE_LIMIT"
    SHUTTING_DOWN = "SHUTTING_DOWN"
    INTERNAL = "INTERNAL"
    SCENE_CONFLICT = "SCENE_CONFLICT"
    STORAGE = "STORAGE"
    # perceive's (src/arduinobot/perception/): what a camera image could not give
    IMAGE_INVALID = "IMAGE_INVALID"
    NO_MARKER = "NO_MARKER"
    UNKNOWN_MARKER = "UNKNOWN_MARKER"
    MARKER_REFUSED = "MARKER_REFUSED"
    # a task's pick and place (src/arduinobot/planner/tasks/): refusals with their numbers
    OBJECT_TOO_WIDE = "OBJECT_TOO_WIDE"
    NO_REACHABLE_GRASP = "NO_REACHABLE_GRASP"
    NO_FREE_PLACE = "NO_FREE_PLACE"
    # the client's own, never sent: no reply at all, or a code it does not know
    UNAVAILABLE = "UNAVAILABLE"
    UNKNOWN = "UNKNOWN"
    # the execute service's (src/arduinobot/service/execute/execution.py) and src/arduinobot/execution/'s, drivers included
    NOT_AT_START = "NOT_AT_START"
    TOO_LATE = "TOO_LATE"
    ROBOT_ERROR = "ROBOT_ERROR"
    PORT_NOT_FOUND = "PORT_NOT_FOUND"
    PORT_BUSY = "PORT_BUSY"
    PORT_ERROR = "PORT_ERROR"
    UNSUPPORTED_ROBOT = "UNSUPPORTED_ROBOT"
    INVALID_SETPOINT = "INVALID_SETPOINT"
    SIMULATION_ERROR = "SIMULATION_ERROR"
    INVALID_TRAJECTORY = "INVALID_TRAJECTORY"
    MOTION_ERROR = "MOTION_ERROR"
    # plug-in drivers (src/arduinobot/execution/robots/plugin.py) and the Feetech bus driver
    DRIVER_NOT_FOUND = "DRIVER_NOT_FOUND"
    NOT_A_DRIVER = "NOT_A_DRIVER"
    SERVO_NO_RESPONSE = "SERVO_NO_RESPONSE"
    SERVO_FAULT = "SERVO_FAULT"
    TRACKING_ERROR = "TRACKING_ERROR"
    INVALID_CALIBRATION = "INVALID_CALIBRATION"
    CALIBRATION_MISMATCH = "CALIBRATION_MISMATCH"


#: The codes the planning service answers with, in ``error.json``'s order.
PLAN_SERVICE_CODES: tuple[Code, ...] = (
    Code.INVALID_REQUEST, Code.START_IN_COLLISION, Code.GOAL_IN_COLLISION,
    Code.GOAL_OUT_OF_REACH, Code.NO_PATH_FOUND, Code.TRAJECTORY_FAILED, Code.INVALID_LIMITS,
    Code.LINE_INTERRUPTED, Code.ORIENTATION_NOT_CONTROLLABLE,
    Code.TIMEOUT, Code.BUSY, Code.RESOURCE_LIMIT, Code.SHUTTING_DOWN, Code.INTERNAL,
    Code.SCENE_CONFLICT, Code.STORAGE, Code.IMAGE_INVALID, Code.NO_MARKER, Code.UNKNOWN_MARKER,
    Code.MARKER_REFUSED, Code.OBJECT_TOO_WIDE, Code.NO_REACHABLE_GRASP, Code.NO_FREE_PLACE)

#: The execute service's and the drivers' codes, in docs/service.md's second table's order.
EXECUTION_CODES: tuple[Code, ...] = (
    Code.NOT_AT_START, Code.TOO_LATE, Code.ROBOT_ERROR, Code.PORT_NOT_FOUND, Code.PORT_BUSY,
    Code.PORT_ERROR, Code.UNSUPPORTED_ROBOT, Code.INVALID_SETPOINT, Code.SIMULATION_ERROR,
    Code.INVALID_TRAJECTORY, Code.MOTION_ERROR, Code.DRIVER_NOT_FOUND, Code.NOT_A_DRIVER,
    Code.SERVO_NO_RESPONSE, Code.SERVO_FAULT, Code.TRACKING_ERROR, Code.INVALID_CALIBRATION,
    Code.CALIBRATION_MISMATCH)
