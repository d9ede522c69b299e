"""The planning service's replies as the client reads them: frozen dataclasses, each parsed
from its JSON body in one place (``PlanReply.parse(body)``, ``FkReply.parse``, ...).

A body is first checked against the schema the service publishes for it
(``src/arduinobot/contract/schema/<kind>_response.json``, by the validator the service checks requests
with, :func:`arduinobot.contract.wire.validator`: ~5 ms for a 20000-point plan), then against what a
schema cannot say (each sample row holds one value per joint). Anything else is refused with
:class:`~arduinobot.client.errors.MalformedReply` naming the field (``trajectory.points[3].effort``):
a service that breaks the contract fails here, not somewhere downstream. What the schema
leaves open (the verification's other figures) stays in :attr:`PlanReply.raw`.
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from itertools import chain
from typing import Any, Literal

import jsonschema_rs
import numpy as np

from arduinobot.client.errors import MalformedReply
from arduinobot.contract.packed import PackedError, unpack
from arduinobot.contract.samples import samples_csv
from arduinobot.contract.wire import field_path, validator

Reply = Literal["plan", "fk", "ik", "check", "task", "scene", "scene_apply", "perceive"]


def _validated(reply: Reply, body: Any) -> Mapping[str, Any]:
    """``body``, if it keeps its schema.

    Raises:
        MalformedReply: naming the first field that breaks it.
    """
    try:
        validator(f"{reply}_response").validate(body)
    except jsonschema_rs.ValidationError as e:
        path = list(e.instance_path)
        if isinstance(e.kind, jsonschema_rs.ValidationErrorKind.Required):
            raise MalformedReply(reply, field_path([*path, e.kind.property]),
                                 "is missing") from None
        raise MalformedReply(reply, field_path(path) or "(root)",
                             f"is invalid ({e.message})") from None
    return body


def _rows(reply: Reply, rows: Sequence[Any], width: int, where: str,
          key: str = "") -> np.ndarray:
    """``rows`` (each ``row[key]`` if ``key``) as an array (m, width).

    Raises:
        MalformedReply: a row that does not hold ``width`` values, one per joint.
    """
    values = [r[key] for r in rows] if key else rows
    for i, row in enumerate(values):
        if len(row) != width:
            at = f"{where}[{i}]" + (f".{key}" if key else "")
            raise MalformedReply(reply, at, f"holds {len(row)} values for {width} joints")
    return np.array(values, float).reshape(len(values), width)


#: the sample arrays of a plan reply's points, in PlanReply's order
_SAMPLE_KEYS = ("positions", "velocities", "accelerations", "effort")
_sample_rows = operator.itemgetter(*_SAMPLE_KEYS)
_sample_time = operator.itemgetter("time_from_start")


def _samples(points: Sequence[Any], width: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The times (m,) and the sample arrays (m, width) in :data:`_SAMPLE_KEYS` order of
    schema-valid ``points``: in one pass, each value read once (not an array per key from
    nested lists: ~2x faster).

    Raises:
        MalformedReply: a row that does not hold ``width`` values, one per joint (the
            first one, key by key, as :func:`_rows` names it).
    """
    m = len(points)
    rows = list(chain.from_iterable(map(_sample_rows, points)))
    lengths = set(map(len, rows))
    if lengths and lengths != {width}:
        for key in _SAMPLE_KEYS:  # raises for the row at fault
            _rows("plan", points, width, "trajectory.points", key)
    flat = np.fromiter(chain.from_iterable(rows), float, len(rows) * width)
    times = np.fromiter(map(_sample_time, points), float, m)
    q, qd, qdd, tau = flat.reshape(m, len(_SAMPLE_KEYS), width).transpose(1, 0, 2).copy()
    return times, q, qd, qdd, tau


def _unpacked(packed: Mapping[str, Any], width: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The times (m,) and the sample arrays (m, width) of a schema-valid
    ``trajectory.packed`` (:func:`arduinobot.contract.packed.unpack`), in :data:`_SAMPLE_KEYS` order.

    Raises:
        MalformedReply: a string that is not base64, or not m (times) or m x width
            numbers, or a number that is not finite.
    """
    try:
        times, q, qd, qdd, tau = unpack(packed, width)
    except PackedError as e:
        raise MalformedReply("plan", e.field, e.problem) from None
    assert qd is not None and qdd is not None and tau is not None  # none is optional here
    return times, q, qd, qdd, tau


def _points_body(body: Mapping[str, Any]) -> Mapping[str, Any]:
    """A plan reply's body with a ``packed`` trajectory written as ``points`` (the v1
    form every reader of JSON takes); a body with points as it is."""
    traj = body["trajectory"]
    if "packed" not in traj:
        return body
    times, *arrays = _unpacked(traj["packed"], len(traj["joint_names"]))
    rows = zip(*(a.tolist() for a in arrays), times.tolist())
    points = [dict(zip((*_SAMPLE_KEYS, "time_from_start"), r)) for r in rows]
    return {**body, "trajectory": {"joint_names": traj["joint_names"], "points": points}}


def _number(v: float | None) -> float | None:
    return None if v is None else float(v)


def _pair(v: Sequence[str] | None) -> tuple[str, str] | None:
    return (v[0], v[1]) if v and all(v) else None


@dataclass(frozen=True)
class Verification:
    """The service's check of the motion it returns (``verification`` in the reply).

    Attributes:
        ok: every limit kept and no collision. certified: collision-freedom proven over
            the continuous motion, not sampled. collision_free: no collision found.
        min_clearance: [m] the certified lower bound on the clearance; None if not measured.
        worst_quantity, worst_ratio: the quantity closest to its (scaled) limit, and its
            peak over that limit.
        closest_pair: the two bodies (links or obstacle ids) at ``min_clearance``; None
            if not measured (or from a service that does not say).
    """

    ok: bool
    certified: bool
    collision_free: bool
    min_clearance: float | None
    worst_quantity: str
    worst_ratio: float
    closest_pair: tuple[str, str] | None = None


@dataclass(frozen=True, eq=False)
class PlanReply:
    """A planned trajectory of the actuated joints (``<prefix>/plan``).

    Attributes:
        joint_names: the column order of every array.
        times: (m,) [s] of the samples; positions [rad], velocities [rad/s],
            accelerations [rad/s²], efforts [N m]: (m, dof) each.
        duration: [s]. path: the collision-checked waypoints, (k, dof) [rad].
        timing: seconds per stage. verification: the service's check of the motion.
        planner, request_id: who planned it, and the request's id.
        raw: the reply as received, a ``packed`` trajectory written as ``points``
            (the v1 JSON to save, replay or execute); ``received``: as it came.
        reached: the tool frame at the end and the residuals to the goal (the reply's
            ``reached``), if sent; ``line``: a straight-line move's report, if one.
    """

    joint_names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    efforts: np.ndarray
    duration: float
    path: np.ndarray
    timing: Mapping[str, float]
    verification: Verification
    planner: str
    request_id: str
    received: Mapping[str, Any] = field(repr=False)
    reached: Mapping[str, Any] | None = None
    line: Mapping[str, Any] | None = None

    @functools.cached_property
    def raw(self) -> Mapping[str, Any]:
        return _points_body(self.received)

    @classmethod
    def parse(cls, body: Any) -> PlanReply:
        """Raises: MalformedReply naming the first field that breaks the contract."""
        b = _validated("plan", body)
        names = b["trajectory"]["joint_names"]
        n = len(names)
        packed = b["trajectory"].get("packed")
        times, q, qd, qdd, tau = _samples(b["trajectory"]["points"], n) if packed is None \
            else _unpacked(packed, n)
        v = b["verification"]
        return cls(tuple(names), times, q, qd, qdd, tau,
                   float(b["duration"]), _rows("plan", b["path"], n, "path"),
                   {k: float(t) for k, t in b["timing"].items()},
                   Verification(v["ok"], v["certified"], v["collision_free"],
                                _number(v["min_clearance"]), v["worst_overall"]["quantity"],
                                float(v["worst_overall"]["ratio"]), _pair(v.get("closest_pair"))),
                   b.get("planner", ""), b["request_id"], b, b.get("reached"), b.get("line"))

    def to_csv(self) -> str:
        """One row per sample, as the planner writes a trajectory
        (:func:`arduinobot.contract.samples.samples_csv`)."""
        return samples_csv(self.joint_names, self.times, self.positions, self.velocities,
                           self.accelerations, self.efforts)


@dataclass(frozen=True, eq=False)
class Pose:
    """A link's pose in the world frame: xyz [m], rpy [rad], the 4x4 matrix."""

    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    matrix: np.ndarray


@dataclass(frozen=True, eq=False)
class CarriedPose(Pose):
    """A carried object's pose in the world frame, and the ``link`` that holds it;
    ``fixed``: added in that link's frame (fixed to it), not attached (picked up)."""

    link: str
    fixed: bool = False


@dataclass(frozen=True, eq=False)
class FkReply:
    """Link poses at ``joints`` [rad] (``<prefix>/fk``); the tcp position [m] if the
    robot has a tcp; ``carried``: where each object the kept scene carries is, by id."""

    joints: Mapping[str, float]
    links: Mapping[str, Pose]
    tcp: tuple[float, float, float] | None
    request_id: str
    carried: Mapping[str, CarriedPose] = field(default_factory=dict)

    @classmethod
    def parse(cls, body: Any) -> FkReply:
        """Raises: MalformedReply naming the first field that breaks the schema."""
        b = _validated("fk", body)
        tcp = b.get("tcp")
        return cls(dict(b["joints"]),
                   {k: Pose(tuple(p["xyz"]), tuple(p["rpy"]), np.array(p["matrix"], float))
                    for k, p in b["links"].items()},
                   None if tcp is None else tuple(tcp), b["request_id"],
                   {k: CarriedPose(tuple(p["xyz"]), tuple(p["rpy"]),
                                   np.array(p["matrix"], float), p["link"],
                                   p.get("fixed", False))
                    for k, p in (b.get("carried") or {}).items()})


@dataclass(frozen=True)
class IkSolution:
    """One IK branch: every actuated joint's value [rad]."""

    joints: Mapping[str, float]
    branch: str


@dataclass(frozen=True)
class IkReply:
    """Every IK branch within the joint limits putting the tcp at the asked position
    (``<prefix>/ik``)."""

    solutions: tuple[IkSolution, ...]
    request_id: str

    @classmethod
    def parse(cls, body: Any) -> IkReply:
        """Raises: MalformedReply naming the first field that breaks the schema."""
        b = _validated("ik", body)
        return cls(tuple(IkSolution(dict(s["joints"]), s["branch"]) for s in b["solutions"]),
                   b["request_id"])


@dataclass(frozen=True)
class CheckReply:
    """One state's check (``<prefix>/check``): ``valid`` and every colliding ``pairs``;
    ``clearance`` [m] to the ``closest`` pair (None when not computed), at ``joints``;
    ``resting``: the (carried object, obstacle) pairs that only touch (a plan from here
    must lift them off with a straight line: ``hint``)."""

    valid: bool
    pairs: tuple[tuple[str, str], ...]
    clearance: float | None
    closest: tuple[str, str] | None
    joints: Mapping[str, float]
    request_id: str
    resting: tuple[tuple[str, str], ...] = ()
    hint: str | None = None

    @classmethod
    def parse(cls, body: Any) -> CheckReply:
        """Raises: MalformedReply naming the first field that breaks the schema."""
        b = _validated("check", body)
        closest = b.get("closest")
        return cls(b["valid"], tuple(tuple(p) for p in b["pairs"]),
                   _number(b["clearance"]),
                   None if closest is None else tuple(closest),
                   dict(b["joints"]), b["request_id"],
                   tuple(tuple(p) for p in b.get("resting") or ()), b.get("hint"))


@dataclass(frozen=True)
class TaskReply:
    """A task planned as a whole (``<prefix>/task``), and run if it was asked to.

    Attributes:
        name: the named task's name (None for a task given whole).
        duration: [s] of the whole task; planning_time: [s] the service took to plan it.
        joint_names: the order of the steps' ``start``/``end`` states.
        steps: each step as the service reports it (index, kind, label, start_time [s],
            duration [s], start, end, carried, and its ``plan`` unless
            ``trajectories=False``).
        planned: the ``planned`` reply as received.
        execution, report: the execution's id and report (outcome, ticks, peaks, and
            ``objects``' simulated end poses from a twin), if it was executed and moved.
        scene_revision: the kept scene's revision the task was planned in (None from a
            service that does not say).
    """

    name: str | None
    duration: float
    planning_time: float
    joint_names: tuple[str, ...]
    steps: tuple[Mapping[str, Any], ...]
    planned: Mapping[str, Any] = field(repr=False)
    execution: str | None = None
    report: Mapping[str, Any] | None = None
    scene_revision: int | None = None

    @classmethod
    def parse(cls, planned: Any, finished: Mapping[str, Any] | None = None) -> TaskReply:
        """``planned``: the first reply; ``finished``: the execution's last event, if any.

        Raises: MalformedReply naming the first field that breaks the schema.
        """
        b = _validated("task", planned)
        if b["event"] != "planned" or "steps" not in b or "duration" not in b:
            raise MalformedReply("task", "event", "is not a planned task")
        report = None
        if finished is not None:
            report = dict(finished.get("report") or {})
            if finished.get("objects"):  # the service's twin simulated them
                report["objects"] = finished["objects"]
        return cls(b.get("name"), float(b["duration"]), float(b.get("planning_time", 0.0)),
                   tuple(b.get("joint_names", ())), tuple(b["steps"]), b,
                   None if finished is None else finished.get("execution"), report,
                   b.get("scene_revision"))


@dataclass(frozen=True)
class SceneReply:
    """The kept planning scene (``<prefix>/scene``): its ``revision``, its free
    ``objects`` as applied (plan_request.json's obstacle form, meshes as sent) and the
    ``attached`` objects the robot carries (each object's xyz/rpy in its link's frame)."""

    revision: int
    objects: tuple[Mapping[str, Any], ...]
    attached: tuple[Mapping[str, Any], ...]

    @classmethod
    def parse(cls, body: Any) -> SceneReply:
        """Raises: MalformedReply naming the first field that breaks the schema."""
        b = _validated("scene", body)
        return cls(int(b["revision"]), tuple(b["objects"]), tuple(b["attached"]))


@dataclass(frozen=True)
class SceneApplied:
    """A scene change applied everywhere (``<prefix>/scene/apply``): the new
    ``revision``, how many ``objects`` and ``attached`` objects the scene now holds, and
    which state an attach, a detach or a cloud used (``request``, ``robot``, ``zero``)."""

    revision: int
    objects: int | None = None
    attached: int | None = None
    state_source: Literal["request", "robot", "zero"] | None = None
    #: each point cloud the apply added: ``{id: {points, kept, dropped, filtered_robot,
    #: filtered_objects, cells, unknown, shadow_cells}}``
    clouds: Mapping[str, Mapping[str, Any]] | None = None
    #: the apply's id had been applied before (``revision`` is the one it made then)
    already_applied: bool = False
    #: live instances that did not take the change (they catch up before planning)
    not_taken_by: tuple[str, ...] = ()
    #: the instance that led the change (the smallest live id that answers)
    leader: str | None = None

    @classmethod
    def parse(cls, body: Any) -> SceneApplied:
        """Raises: MalformedReply naming the first field that breaks the schema."""
        b = _validated("scene_apply", body)
        return cls(int(b["revision"]), b.get("objects"), b.get("attached"),
                   b.get("state_source"), b.get("clouds"), bool(b.get("already_applied")),
                   tuple(b.get("not_taken_by") or ()), b.get("leader"))


@dataclass(frozen=True)
class Detection:
    """An object seen through its marker (world frame): the object's pose ``xyz`` [m] /
    ``rpy`` [rad], the marker's, the corners' RMS ``reprojection_error`` [px] and the
    ``uncertainty`` [m] the object was padded by."""

    marker: int
    object: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    marker_xyz: tuple[float, float, float]
    marker_rpy: tuple[float, float, float]
    reprojection_error: float
    uncertainty: float


def _vec3(v: Sequence[float]) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


@dataclass(frozen=True)
class PerceiveReply:
    """What a camera image showed (``<prefix>/perceive``): the ``detections``, the
    ``camera`` (its link, optical frame and pose in the world), the ``intrinsics`` used,
    with ``apply`` the kept scene's new ``revision`` and the ids ``removed`` as unseen,
    and for a topic's image where it came from (``image``: topic, frame_id, stamp, size,
    encoding)."""

    detections: tuple[Detection, ...]
    camera: Mapping[str, Any]
    intrinsics: Mapping[str, Any]
    revision: int | None
    removed: tuple[str, ...]
    image: Mapping[str, Any] | None
    raw: Mapping[str, Any]

    @classmethod
    def parse(cls, body: Any) -> PerceiveReply:
        """Raises: MalformedReply naming the first field that breaks the schema."""
        b = _validated("perceive", body)
        dets = tuple(Detection(int(d["marker"]), str(d["object"]), _vec3(d["xyz"]),
                               _vec3(d["rpy"]), _vec3(d["marker_xyz"]), _vec3(d["marker_rpy"]),
                               float(d["reprojection_error"]), float(d["uncertainty"]))
                     for d in b["detections"])
        return cls(dets, b["camera"], b.get("intrinsics", {}),
                   None if "revision" not in b else int(b["revision"]),
                   tuple(b.get("removed", ())), b.get("image"), b)
