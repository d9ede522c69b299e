"""The errors a :class:`arduinobot.client.client.PlannerClient` raises: one class per wire code.

:class:`ServiceError` is the root; ``code``, ``message`` and ``details`` come from the
service's ``{"error": {...}}`` reply. :class:`ServiceUnavailable` means no reply at all,
with ``reason`` saying what the client could tell apart.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from arduinobot.contract.codes import Code


class ServiceError(Exception):
    """Root of every client error. ``details`` is the reply's JSON object."""

    code: str = Code.UNKNOWN

    def __init__(self, message: str, *, code: str | None = None,
                 details: Mapping[str, Any] | None = None) -> None:
        if code is not None:
            self.code = code
        self.message = message
        self.details = dict(details or {})
        super().__init__(f"{self.code}: {message}")


class InvalidRequest(ServiceError):
    """A field is malformed, unknown, non-finite or out of range (``details.field``)."""
    code: str = Code.INVALID_REQUEST


class StartInCollision(ServiceError):
    """The start state collides (``details.pairs``)."""
    code: str = Code.START_IN_COLLISION


class GoalInCollision(ServiceError):
    """The goal state collides (``details.pairs``)."""
    code: str = Code.GOAL_IN_COLLISION


class GoalOutOfReach(ServiceError):
    """No joint state within limits reaches the goal position."""
    code: str = Code.GOAL_OUT_OF_REACH


class NoPathFound(ServiceError):
    """No collision-free path within the planning time."""
    code: str = Code.NO_PATH_FOUND


class TrajectoryFailed(ServiceError):
    """No timing of the path passed verification (``details.report``)."""
    code: str = Code.TRAJECTORY_FAILED


class InvalidLimits(ServiceError):
    """The robot's joint limits are missing or invalid."""
    code: str = Code.INVALID_LIMITS


class LineInterrupted(ServiceError):
    """A straight-line move cannot go the whole way (``details.fraction``, ``details.reason``)."""
    code: str = Code.LINE_INTERRUPTED


class OrientationNotControllable(ServiceError):
    """A pose goal constrains an orientation the group cannot choose
    (``details.controllable_axes``)."""
    code: str = Code.ORIENTATION_NOT_CONTROLLABLE


class RequestTimeout(ServiceError):
    """The service's deadline for the request passed (it answered TIMEOUT)."""
    code: str = Code.TIMEOUT


class ServiceBusy(ServiceError):
    """Every worker is busy and the queue is full: retry later or add instances."""
    code: str = Code.BUSY


class ResourceLimit(ServiceError):
    """The request needed more memory than a worker may use (``details.memory_cap``
    [bytes]); that worker has been replaced. Ask for less (samples, scalings)."""
    code: str = Code.RESOURCE_LIMIT


class ShuttingDown(ServiceError):
    """The instance is stopping; retry at once (another instance takes the key)."""
    code: str = Code.SHUTTING_DOWN


class InternalError(ServiceError):
    """The service failed (a bug, or a worker crash: that worker has been replaced)."""
    code: str = Code.INTERNAL


class SceneConflict(ServiceError):
    """The scene is not at the revision the request named (``details.field``:
    ``if_revision`` or ``scene_revision``); ``details.current_revision`` is where it is:
    read the scene again and retry."""
    code: str = Code.SCENE_CONFLICT


class StorageError(ServiceError):
    """The instance could not keep the scene on its disk (full, read-only:
    ``details.errno``); nothing changed. Retry once the disk is fixed."""
    code: str = Code.STORAGE



class ImageInvalid(ServiceError):
    """perceive: the image is not a PNG/JPEG that decodes, or is all one colour."""
    code: str = Code.IMAGE_INVALID


class NoMarker(ServiceError):
    """perceive: no marker of the dictionary (``details.dictionary``) is in the image."""
    code: str = Code.NO_MARKER


class UnknownMarker(ServiceError):
    """perceive: markers whose ids the map lacks are seen (``details.markers``)."""
    code: str = Code.UNKNOWN_MARKER


class MarkerRefused(ServiceError):
    """perceive: a marker is seen too small or at a grazing angle (``details.reason``)."""
    code: str = Code.MARKER_REFUSED


class ObjectTooWide(ServiceError):
    """task: a pick's object is wider between the fingers (``details.width`` [m]) than
    the claw opens (``details.opening`` [m])."""
    code: str = Code.OBJECT_TOO_WIDE


class NoReachableGrasp(ServiceError):
    """task: no grasp candidate of a pick is within the arm's reach
    (``details.closest_residual`` [m]: the closest one's miss)."""
    code: str = Code.NO_REACHABLE_GRASP


class NoFreePlace(ServiceError):
    """task: every spot of a place is taken (``details.blocking``: the object in the
    way of the first)."""
    code: str = Code.NO_FREE_PLACE

class MalformedReply(ServiceError):
    """A reply this client cannot read: a field its schema requires is missing or of the
    wrong type (``details.field``, ``details.reply``: plan, fk, ik or check). The service
    and this client do not keep the same contract (a different version?). Its code is
    ``UNKNOWN``: the service sent none."""

    def __init__(self, reply: str, field: str, problem: str) -> None:
        self.field = field
        super().__init__(f"the {reply} reply's {field} {problem}",
                         details={"field": field, "reply": reply})


UnavailableReason = Literal["connect_failed", "no_route", "timeout", "zenoh_error"]


class ServiceUnavailable(ServiceError):
    """No answer from any service.

    ``reason``:
        ``connect_failed``: no Zenoh session could be opened to the endpoints;
        ``no_route``: the session is up but nothing serves the key (no service running
        under this prefix, or access control hides it);
        ``timeout``: a service took the query but no reply came in time;
        ``zenoh_error``: Zenoh itself answered with an error (``details.zenoh``).
    """

    code: str = Code.UNAVAILABLE

    def __init__(self, message: str, *, reason: UnavailableReason,
                 details: Mapping[str, Any] | None = None) -> None:
        self.reason = reason
        super().__init__(message, details={**(details or {}), "reason": reason})


#: every class above for a code the service sends (not the client's own two)
ERRORS: dict[str, type[ServiceError]] = {c.code: c for c in ServiceError.__subclasses__()
                                         if c not in (MalformedReply, ServiceUnavailable)}


def error_from_reply(body: Mapping[str, Any]) -> ServiceError:
    """The exception for an ``{"error": {"code", "message", "details"}}`` reply; an
    unknown code gives a plain :class:`ServiceError` carrying it."""
    err = body.get("error", {}) if isinstance(body, Mapping) else {}
    code = str(err.get("code", Code.UNKNOWN))
    message = str(err.get("message", ""))
    details = err.get("details") if isinstance(err.get("details"), Mapping) else {}
    cls = ERRORS.get(code)
    return cls(message, details=details) if cls else ServiceError(message, code=code,
                                                                   details=details)
