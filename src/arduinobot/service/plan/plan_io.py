"""Plan requests and responses on the wire <-> :mod:`arduinobot.planner.planning.pipeline`.

Shared by the service's workers and ``arduinobot plan --local [--request FILE]``, so a
request is parsed, refused and answered the same way in both.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Literal

import numpy as np
import orjson

from arduinobot.contract.caps import MAX_SAMPLES
from arduinobot.contract.errors import PlanningError
from arduinobot.contract.packed import pack
from arduinobot.contract.wire import check_finite
from arduinobot.description import Description
from arduinobot.planner.planning.goals import Goal, goal_from_mapping
from arduinobot.planner.planning.pipeline import MotionRequest
from arduinobot.planner.timing.trajectory import check_sample_count
from arduinobot.scene.obstacles import AttachedObject, resolve_attached
from arduinobot.scene.state import SceneSnapshot, with_scene
from arduinobot.service.plan.requests import obstacles

#: the reply's trajectory: a sample object per point, or each array in one base64 string
TrajectoryFormat = Literal["points", "packed"]

#: a plan request's options, each as :class:`~arduinobot.planner.planning.pipeline.MotionRequest` takes it
#: (JSON Schema counts 7.0 as an integer: the planner wants an int seed)
_OPTIONS: dict[str, Callable[[Any], Any]] = {
    "group": str, "planner": str, "planning_time": float, "velocity_scaling": float,
    "acceleration_scaling": float, "profile": str, "sample_rate": float, "seed": int,
    "start_velocity": dict, "start_acceleration": dict, "ground": bool}


def goal(description: Description, data: Mapping[str, Any]) -> Goal:
    """The goal of a plan request (:func:`arduinobot.planner.planning.goals.goal_from_mapping`;
    joint names and limits, a named state's group: checked by the planner)."""
    return goal_from_mapping(data, "goal")


def attached(description: Description, items: Any, *, scene: SceneSnapshot | None = None,
             obstacles: tuple = ()) -> tuple[AttachedObject, ...]:
    """The carried objects of a request: the kept ``scene``'s (if it holds any), then the
    request's own ``attached`` items (the wire format of
    :meth:`arduinobot.scene.obstacles.AttachedObject.from_mapping`), checked against the robot."""
    kept = tuple(getattr(scene, "attached", ()) or ()) if scene is not None else ()
    own = tuple(AttachedObject.from_mapping(a, where=f"attached[{i}]")
                for i, a in enumerate(items or ()))
    return resolve_attached(description, kept + own, obstacles=obstacles)


def plan_request(description: Description, data: Mapping[str, Any], *,
                 scene: SceneSnapshot | None = None) -> MotionRequest:
    """A validated v1 plan request (see ``src/arduinobot/contract/schema/plan_request.json``) as a
    :class:`arduinobot.planner.planning.motion.MotionRequest` whose obstacles are the kept
    ``scene``'s plus the request's own (see :func:`arduinobot.scene.state.with_scene`), and
    whose carried objects are the scene's plus the request's ``attached`` (for it
    alone). A missing start is all actuated joints at 0."""
    opts = {k: convert(data[k]) for k, convert in _OPTIONS.items() if k in data}
    obs, _ = with_scene(scene, data, obstacles(description, data.get("obstacles")))
    return MotionRequest(
        goal=goal(description, data["goal"]),
        start=data.get("start"),  # names and limits: checked by the planner, once
        obstacles=obs,
        attached=attached(description, data.get("attached"), scene=scene, obstacles=obs),
        clouds=scene.clouds if scene is not None else (),
        max_samples=MAX_SAMPLES,  # refused before sampling, not after
        **opts)


def plan_response(result: Any, *, trajectory_format: TrajectoryFormat = "points"
                  ) -> dict[str, Any]:
    """A :class:`arduinobot.planner.planning.pipeline.MotionResult` as the v1 response (without request_id):
    trajectory (actuated joints; ``points`` or, ``packed``, each array in one string),
    duration [s], path (waypoints in joint_names order), timing (seconds per stage),
    verification, planner.

    Raises:
        InvalidRequest: more than :data:`arduinobot.contract.caps.MAX_SAMPLES` samples (field
            ``sample_rate``), before any of the reply is built.
    """
    traj = _checked(result)
    if trajectory_format == "packed":
        body = _body(result, None, packed=_packed(traj))
    else:
        # from the sample arrays (m, dof): much faster than per-point objects
        columns = zip(traj.positions.tolist(), traj.velocities.tolist(),
                      traj.accelerations.tolist(), traj.efforts.tolist(), traj.times.tolist())
        body = _body(result, [{"positions": q, "velocities": qd, "accelerations": qdd,
                               "effort": tau, "time_from_start": t}
                              for q, qd, qdd, tau, t in columns])
    body["path"] = np.asarray(result.path, float).tolist()
    return body  # every number finite: wire.encode(..., finite=True) may take it


def plan_reply(result: Any, request_id: str, *, scene_revision: int = 0,
               trajectory_format: TrajectoryFormat = "points",
               clouds: Mapping[str, str] | None = None) -> bytes:
    """:func:`plan_response`'s body with ``request_id``, encoded: the same JSON (keys,
    order and numbers; orjson writes a float64 of an array as it writes the float), built
    from the sample arrays without a Python object per sample (what a worker sends).

    Raises:
        InvalidRequest: as :func:`plan_response`.
    """
    traj = _checked(result)
    if trajectory_format == "packed":
        body = _body(result, None, packed=_packed(traj))
    else:
        body = _body(result, orjson.Fragment(_points_json(traj)))
    body["path"] = np.ascontiguousarray(result.path, dtype=np.float64)
    body["scene_revision"] = scene_revision
    if clouds:  # a plan that used a cloud says what it took unseen space to be
        body["clouds"] = dict(clouds)
    body["request_id"] = request_id
    return orjson.dumps(body, option=orjson.OPT_SERIALIZE_NUMPY)


def _packed(traj: Any) -> dict[str, Any]:
    """``trajectory.packed`` (:func:`arduinobot.contract.packed.pack`: what the schema says)."""
    return pack(traj.times, traj.positions, traj.velocities, traj.accelerations, traj.efforts)


#: what joins the parts of one sample: its row of each array, then its time
_POINT_KEYS = (b'{"positions":[', b'],"velocities":[', b'],"accelerations":[',
               b'],"effort":[', b'],"time_from_start":')


def _points_json(traj: Any) -> bytes:
    """``trajectory.points`` as JSON text: each (m, dof) array and the times written by
    orjson at once, cut into rows, and interleaved with the keys by numpy (no loop in
    Python over the samples)."""
    m = len(traj.times)
    if m == 0:
        return b"[]"
    parts = np.empty((m, 11), dtype=object)
    parts[:, 0:10:2] = _POINT_KEYS
    parts[:, 10] = b"},"
    parts[-1, 10] = b"}"
    for col, a in enumerate((traj.positions, traj.velocities, traj.accelerations,
                             traj.efforts)):
        text = orjson.dumps(np.ascontiguousarray(a, dtype=np.float64),
                            option=orjson.OPT_SERIALIZE_NUMPY)
        # b"[[r0],[r1],...]": rows hold numbers only, so "],[" is exactly where they meet
        parts[:, 2 * col + 1] = text[2:-2].split(b"],[")
    times = orjson.dumps(np.ascontiguousarray(traj.times, dtype=np.float64),
                         option=orjson.OPT_SERIALIZE_NUMPY)
    parts[:, 9] = times[1:-1].split(b",")
    return b"[" + b"".join(parts.ravel().tolist()) + b"]"


def _checked(result: Any) -> Any:
    """``result.trajectory`` once its sample count is within the cap and every array of
    the reply is finite."""
    traj = result.trajectory
    # the planner refuses before sampling too (max_samples): this guards the reply itself
    check_sample_count(len(traj.times), duration=float(traj.duration),
                       sample_rate=float(traj.sample_rate), limit=MAX_SAMPLES, cap="MAX_SAMPLES")
    arrays = {"positions": traj.positions, "velocities": traj.velocities,
              "accelerations": traj.accelerations, "effort": traj.efforts,
              "time_from_start": traj.times, "path": result.path}
    for name, a in arrays.items():
        if not np.isfinite(np.asarray(a, float)).all():
            raise PlanningError(f"the planner returned non-finite {name}")
    return traj


def _body(result: Any, points: Any, *, packed: dict[str, Any] | None = None
          ) -> dict[str, Any]:
    """The response's fields in their order, ``path`` still to fill; the trajectory's
    samples as ``points``, or ``packed`` if given."""
    traj = result.trajectory
    samples = {"points": points} if packed is None else {"packed": packed}
    body = {
        "trajectory": {"joint_names": list(traj.joint_names), **samples},
        "duration": float(traj.duration),
        "path": None,
        "timing": {str(k): float(v) for k, v in dict(result.timing).items()},
        "verification": result.verification.to_dict(),
        "planner": str(result.planner),
    }
    if result.reached is not None:
        body["reached"] = result.reached.to_dict()
    if result.line is not None:
        body["line"] = result.line.to_dict()
    if getattr(result, "lifted_off", ()):  # a line from a resting start
        body["lifted_off"] = [list(p) for p in result.lifted_off]
    check_finite({k: body[k] for k in ("duration", "timing", "verification", "reached",
                                       "line") if k in body})
    return body  # every number finite: wire.encode(..., finite=True) may take it
