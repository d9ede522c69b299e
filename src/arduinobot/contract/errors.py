"""Every way planning can fail, one exception class each, under :class:`PlanningError`.

Each carries what a user needs to act: the field, the joints, the colliding pairs.
``code`` is the wire error code the service sends.
"""

from __future__ import annotations

import difflib
import errno
import os
from collections.abc import Iterable, Mapping, Sequence

from arduinobot.contract.codes import Code


class PlanningError(Exception):
    """Root of every planner error. ``details`` is JSON-ready."""

    code: Code = Code.INTERNAL

    def __init__(self, message: str, *, details: Mapping[str, object] | None = None) -> None:
        self.message = message
        self.details = dict(details or {})
        super().__init__(message)


def unknown_names(given: Iterable[str], known: Iterable[str]) -> str:
    """``given`` names (those not in ``known``) as a refusal lists them, each with the
    closest known name when one is close: ``'stpes' (did you mean 'steps'?), 'x'``."""
    choices = sorted(known)
    out = []
    for name in given:
        close = difflib.get_close_matches(name, choices, n=1, cutoff=0.6)
        out.append(f"'{name}'" + (f" (did you mean '{close[0]}'?)" if close else ""))
    return ", ".join(out)


def unknown_fields(extra: Sequence[str], known: Iterable[str], *, of: str = "") -> str:
    """The refusal of the unknown keys ``extra`` of a JSON object whose keys are
    ``known``: ``unknown field 'lable' (did you mean 'label'?) of a gripper step; it takes
    ...``."""
    allowed = sorted(set(known))
    return (f"unknown field{'s' if len(extra) > 1 else ''} {unknown_names(extra, allowed)}"
            f"{f' of {of}' if of else ''}; it takes {', '.join(allowed)}")


class InvalidRequest(PlanningError):
    """A request field is malformed or out of range."""

    code: Code = Code.INVALID_REQUEST

    def __init__(self, message: str, *, field: str | None = None,
                 details: Mapping[str, object] | None = None) -> None:
        self.field = field
        d = dict(details or {})
        if field is not None:
            d.setdefault("field", field)
        super().__init__(f"{field}: {message}" if field else message, details=d)


class JointLimitViolation(InvalidRequest):
    """A joint value lies outside its position limits."""

    def __init__(self, joint: str, value: float, lower: float, upper: float, *,
                 field: str) -> None:
        self.joint, self.value, self.lower, self.upper = joint, value, lower, upper
        super().__init__(f"{joint} = {value:.6g} rad is outside its limits "
                         f"[{lower:.6g}, {upper:.6g}]", field=field,
                         details={"joint": joint, "value": value, "lower": lower,
                                  "upper": upper})


class StateInCollision(PlanningError):
    """A state collides; ``pairs`` lists every colliding pair (link/link or link/obstacle)."""

    def __init__(self, message: str, *, pairs: Sequence[tuple[str, str]],
                 q: Mapping[str, float] | None = None) -> None:
        self.pairs = [tuple(p) for p in pairs]
        details: dict[str, object] = {"pairs": [list(p) for p in self.pairs]}
        if q is not None:
            details["q"] = dict(q)
        super().__init__(f"{message}: " + ", ".join(f"{a}/{b}" for a, b in self.pairs),
                         details=details)


class StartInCollision(StateInCollision):
    code: Code = Code.START_IN_COLLISION


class GoalInCollision(StateInCollision):
    code: Code = Code.GOAL_IN_COLLISION


class GoalOutOfReach(PlanningError):
    """No joint state within limits puts the tcp at the requested position."""

    code: Code = Code.GOAL_OUT_OF_REACH


class NoPathFound(PlanningError):
    """The planner found no collision-free path within its time budget."""

    code: Code = Code.NO_PATH_FOUND


class TrajectoryError(PlanningError):
    """Time parameterisation failed or could not be verified within the limits."""

    code: Code = Code.TRAJECTORY_FAILED


class ObjectTooWide(PlanningError):
    """A pick's object is wider between the fingers than the claw opens, in every
    reachable grasp (``details``: object, width [m], opening [m])."""

    code: Code = Code.OBJECT_TOO_WIDE


class NoReachableGrasp(PlanningError):
    """No grasp candidate of a pick (or no spot of a place) is within the arm's reach
    (``details``: object, candidates, closest_residual [m], closest)."""

    code: Code = Code.NO_REACHABLE_GRASP


class NoFreePlace(PlanningError):
    """Every spot a place tried would put the object into another one (``details``:
    object, blocking: the object in the way of the first spot, spots)."""

    code: Code = Code.NO_FREE_PLACE


class LineInterrupted(PlanningError):
    """A straight-line move cannot go the whole way: the line leaves the workspace,
    crosses a joint limit or a collision. The line is never bent round it.

    ``fraction``: how far along the line [0, 1] the tcp got before it (MoveIt's
    computeCartesianPath fraction); ``reason``: ``out_of_workspace``, ``joint_limit``,
    ``collision`` or ``singularity`` (the joints would have to jump to stay on the line).
    """

    code: Code = Code.LINE_INTERRUPTED

    def __init__(self, message: str, *, fraction: float, reason: str,
                 details: Mapping[str, object] | None = None) -> None:
        self.fraction, self.reason = float(fraction), reason
        d = {"fraction": self.fraction, "reason": reason, **dict(details or {})}
        super().__init__(f"{message} (after {100 * self.fraction:.1f}% of the line)",
                         details=d)


class OrientationNotControllable(PlanningError):
    """A pose goal constrains an orientation the group cannot choose (a position-only
    arm): ``controllable`` names the axes its joints turn the tool about, and the
    details say what orientation the position gives and how far that is from the goal."""

    code: Code = Code.ORIENTATION_NOT_CONTROLLABLE

    def __init__(self, message: str, *, controllable: Sequence[Mapping[str, object]],
                 details: Mapping[str, object] | None = None) -> None:
        self.controllable = [dict(c) for c in controllable]
        d = {"controllable_axes": self.controllable, **dict(details or {})}
        super().__init__(message, details=d)


class LimitsError(PlanningError):
    """A joint's limits are missing or invalid, and no documented rule can derive them."""

    code: Code = Code.INVALID_LIMITS

    def __init__(self, message: str, *, joint: str, limit: str,
                 details: Mapping[str, object] | None = None) -> None:
        self.joint, self.limit = joint, limit
        d = {"joint": joint, "limit": limit, **dict(details or {})}
        super().__init__(f"{joint} {limit}: {message}", details=d)


class ShuttingDown(PlanningError):
    """The service instance is stopping and did not take (or finish) the request."""

    code: Code = Code.SHUTTING_DOWN


class StorageError(PlanningError):
    """This machine's disk refused a write the request needs (full, read-only, over a
    quota): ``details.errno`` names the OS error; the message names what was being kept,
    never a path of the server."""

    code: Code = Code.STORAGE

    @classmethod
    def of(cls, err: OSError, what: str) -> StorageError:
        """The refusal of ``err`` (an OSError of writing ``what``: "the scene's file"),
        without its file names."""
        name = errno.errorcode.get(err.errno or 0, errno.errorcode[errno.EIO])
        reason = os.strerror(err.errno) if err.errno else "input/output error"
        return cls(f"could not write {what} on this instance's disk: {reason.lower()} "
                   f"({name})", details={"errno": name})


class SceneConflict(PlanningError):
    """The scene is not at the revision a request names (``field``: ``if_revision`` of a
    scene apply, ``scene_revision`` of a plan or check); ``details.current_revision``
    says where it is."""

    code: Code = Code.SCENE_CONFLICT

    def __init__(self, message: str, *, field: str, current_revision: int,
                 details: Mapping[str, object] | None = None) -> None:
        self.field, self.current_revision = field, current_revision
        super().__init__(f"{field}: {message}", details={
            **dict(details or {}), "field": field, "current_revision": current_revision})
