"""The Python client of the arduinobot service.

    from arduinobot.client.client import PlannerClient
    with PlannerClient() as c:                      # tcp/127.0.0.1:7447
        res = c.plan({"goal": {"named": "reach_forward"}})
        print(res.duration, res.positions.shape)

Each reply comes back as its frozen dataclass (:mod:`arduinobot.client.replies`), checked against
its schema; every service error raises its own class (:mod:`arduinobot.client.errors`), no reply
at all :class:`~arduinobot.client.errors.ServiceUnavailable` with a hint. With ``spread=True`` each
request goes to the least loaded live instance (:mod:`arduinobot.client.balance`).
"""

from __future__ import annotations

import base64
import logging
import os
import threading
import uuid
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import zenoh

from arduinobot.client.balance import LoadBalancer
from arduinobot.client.codec import decode_reply, encode_body, plan_body, planning_time
from arduinobot.client.errors import (
    MalformedReply,
    ServiceBusy,
    ServiceUnavailable,
)
from arduinobot.client.replies import (
    CheckReply,
    FkReply,
    IkReply,
    PerceiveReply,
    PlanReply,
    SceneApplied,
    SceneReply,
    TaskReply,
)
from arduinobot.client.scene_update import update_scene
from arduinobot.client.stream import ExecutionEvent, cancel_execution, follow, stream
from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.outcomes import DEFAULT_ON_CHANGE, ON_CHANGE
from arduinobot.contract.wire import JSON
from arduinobot.contract.zconfig import (
    DEFAULT_ENDPOINT,
    DEFAULT_PREFIX,
    zenoh_config,
    zenoh_message,
)

_log = logging.getLogger(__name__)

_HINT = ("start one with `arduinobot serve` (or `./dev arduinobot serve`), or check the "
         "endpoint (--connect) and the prefix")


class PlannerClient:
    """A Zenoh session to the arduinobot service.

    Args:
        endpoints: where to connect (a service listening, or a router).
        prefix: the service's key prefix.
        timeout: seconds to wait for a reply (plans add their planning_time).
        config_file: a zenoh JSON5 config (TLS, credentials); options here override it.
        spread: send each request to the least loaded live instance, and to another
            one if it has gone or is BUSY.

    Raises:
        ServiceUnavailable: ``reason="connect_failed"`` if no session could be opened.
    """

    def __init__(self, endpoints: Sequence[str] | str = (DEFAULT_ENDPOINT,), *,
                 prefix: str = DEFAULT_PREFIX, timeout: float = 60.0,
                 config_file: str | Path | None = None, spread: bool = False) -> None:
        self.endpoints = [endpoints] if isinstance(endpoints, str) else list(endpoints)
        self.prefix, self.timeout, self.spread = prefix, float(timeout), spread
        try:
            self.session = zenoh.open(zenoh_config(mode="client", connect=self.endpoints,
                                                   listen=[], config_file=config_file))
        except zenoh.ZError as e:
            raise ServiceUnavailable(
                f"cannot reach {', '.join(self.endpoints)}: {zenoh_message(e)}; {_HINT}",
                reason="connect_failed", details={"endpoints": self.endpoints}) from None
        self.balancer = LoadBalancer(self.session, prefix)

    # -- lifecycle ---------------------------------------------------------------------
    def close(self) -> None:
        if not self.session.is_closed():
            self.session.close()

    def __enter__(self) -> PlannerClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- discovery ---------------------------------------------------------------------
    def instances(self, *, refresh: bool = False) -> tuple[str, ...]:
        """The ids of the live instances (liveliness tokens ``<prefix>/alive/<id>``)."""
        return self.balancer.live(refresh=refresh)

    def connected(self) -> bool:
        """Whether the session has a link to a router or a peer right now."""
        info = self.session.info
        return bool(list(info.routers_zid()) or list(info.peers_zid()))

    # -- requests ----------------------------------------------------------------------
    def request(self, kind: str, body: Mapping[str, Any] | bytes | str | None = None, *,
                instance: str | None = None, timeout: float | None = None) -> dict[str, Any]:
        """Send one query and return the decoded JSON reply.

        Args:
            kind: ``plan``, ``fk``, ``ik``, ``check``, ``health``, ``description``, ``schema``.
            body: the request (a mapping is JSON-encoded; bytes/str go as they are).
            instance: address one instance (default: the shared key, or with ``spread``
                the least loaded live instance).
            timeout: seconds to wait (default: the client's, plus a plan's planning_time).

        Raises:
            ServiceError subclasses for error replies; ServiceUnavailable for none.
        """
        payload = encode_body(body)
        wait = float(timeout) if timeout is not None else \
            self.timeout + (planning_time(body) if kind == "plan" else 0.0)
        if instance is not None:
            key = f"{self.prefix}/instance/{instance}/{kind}"
        else:
            key = f"{self.prefix}/{kind}"
            if self.spread:
                answer = self._spread(kind, payload, wait)
                if answer is not None:
                    return answer
                # every instance we knew has gone: the shared key reaches any other
        replies = self._get(key, payload, wait)
        if not replies:
            raise self._no_reply(key)
        return decode_reply(replies[0], key, wait)

    def _spread(self, kind: str, payload: bytes | None, wait: float) -> dict[str, Any] | None:
        """The reply of the least loaded instance that answers and is not BUSY, trying
        each live instance at most once; None if none answered at all."""
        tried: list[str] = []
        busy: ServiceBusy | None = None
        while (inst := self.balancer.pick(exclude=tried)) is not None:
            tried.append(inst)
            key = f"{self.prefix}/instance/{inst}/{kind}"
            with self.balancer.sending(inst):
                replies = self._get(key, payload, wait)
            if not replies:  # it has just gone (or is going): the next one
                _log.info("instance %s did not answer on %s; trying another", inst, key)
                self.balancer.forget(inst)
                continue
            try:
                return decode_reply(replies[0], key, wait)
            except ServiceBusy as e:  # its queue is full: another may have room
                busy = e
        if busy is not None:
            raise busy  # every instance was busy: the service's own retry hint
        return None

    def _no_reply(self, key: str) -> ServiceUnavailable:
        if self.connected():
            return ServiceUnavailable(f"no service answered on '{key}' via "
                                      f"{', '.join(self.endpoints)}: {_HINT}",
                                      reason="no_route", details={"key": key,
                                                                  "connected": True})
        return ServiceUnavailable(
            f"no reply on '{key}': the link to {', '.join(self.endpoints)} is down (a router "
            "restarting, or the network); the request went unanswered: retry once it is "
            "back (the session reconnects by itself)", reason="no_route",
            details={"key": key, "connected": False})

    def _get(self, key: str, payload: bytes | None, wait: float) -> list[zenoh.Reply]:
        """The first reply to a get on ``key`` (none: an empty list). The first is the
        answer: taken as it arrives, not once the query is finalised (a wake later)."""
        replies = self.session.get(key, payload=payload, timeout=wait,
                                   encoding=JSON if payload else None)
        for reply in replies:
            return [reply]
        return []

    def plan(self, request: Mapping[str, Any] | None = None, *,
             instance: str | None = None, **fields: Any) -> PlanReply:
        """Plan: a whole v1 request, or its fields as keywords (``goal={"named": "home"}``).

        The trajectory comes ``packed`` (each array in one base64 string: a smaller reply,
        parsed without a Python number per value) unless the request sets
        ``trajectory_format``; :attr:`PlanReply.raw` writes it as ``points`` either way.

        Raises:
            InvalidRequest, StartInCollision, GoalInCollision, GoalOutOfReach, NoPathFound,
            TrajectoryFailed, RequestTimeout, ServiceBusy, InternalError, ServiceUnavailable,
            MalformedReply.
        """
        return PlanReply.parse(self.request("plan", plan_body(request, **fields),
                                            instance=instance))

    def fk(self, joints: Mapping[str, float] | None = None, *,
           links: Sequence[str] | None = None) -> FkReply:
        """Link poses at ``joints`` [rad] (missing joints are 0)."""
        req: dict[str, Any] = {"joints": dict(joints or {})}
        if links is not None:
            req["links"] = list(links)
        return FkReply.parse(self.request("fk", req))

    def ik(self, position: Sequence[float]) -> IkReply:
        """Every IK branch putting the tcp at ``position`` [m] (GoalOutOfReach if none)."""
        return IkReply.parse(self.request("ik", {"position": [float(v) for v in position]}))

    def check_state(self, joints: Mapping[str, float] | None = None, *,
                    obstacles: Sequence[Mapping[str, Any]] = (),
                    padding: float = 0.0, ground: bool = True) -> CheckReply:
        """Whether a state is collision-free among ``obstacles`` (and the ground, the
        plane the base stands on, unless ``ground`` is false), with clearance [m]."""
        req: dict[str, Any] = {"joints": dict(joints or {})}
        if obstacles:
            req["obstacles"] = list(obstacles)
        if padding:
            req["padding"] = padding
        if not ground:
            req["ground"] = False
        return CheckReply.parse(self.request("check", req))

    # -- moving the service's robot (see arduinobot.client.stream) -----------------------
    def execute(self, trajectory: Mapping[str, Any] | None = None, *,
                plan: Mapping[str, Any] | None = None, start_tolerance: float = 0.01,
                move_to_start: bool = False, on_change: str = DEFAULT_ON_CHANGE,
                on_event: Callable[[ExecutionEvent], None] | None = None,
                cancel: threading.Event | None = None) -> ExecutionEvent:
        """Move the service's robot along ``trajectory`` (a plan reply or ``{joint_names,
        points}``), or along a plan of ``plan`` (a v1 request; without ``start``, from
        the robot's state); returns the ``finished`` event with the report.

        Args:
            on_change: when the kept scene changes while it moves and the rest of the
                motion is no longer certified: ``replan`` (stop before it, plan on to
                the same goal), ``stop`` (stop before it; outcome ``stopped``) or
                ``ignore`` (:data:`arduinobot.contract.outcomes.ON_CHANGE`).
            on_event: called with each event (started, progress, changed, stopped,
                replanned, finished; :func:`arduinobot.client.stream.describe` says a
                reaction's in a line).
            cancel: set it (from any thread) to stop the arm smoothly; another client
                can stop it too, with :meth:`cancel_execution` and the execution id.

        Raises:
            InvalidRequest, InvalidTrajectory, NotAtStart, ServiceBusy (the arm is
            moving), a robot's coded error (PortError mid-motion: ``details`` hold the
            last setpoint the arm took), ServiceUnavailable (no reply, or a stream
            silent for longer than the client's timeout plus the planning time).
        """
        if (trajectory is None) == (plan is None):
            raise TypeError("give exactly one of trajectory and plan")
        if on_change not in ON_CHANGE:
            raise InvalidRequest(f"on_change {on_change!r} must be one of "
                                 f"{', '.join(ON_CHANGE)}", field="on_change")
        body: dict[str, Any] = {"start_tolerance": start_tolerance,
                                "move_to_start": move_to_start, "on_change": on_change}
        if trajectory is not None:
            body["trajectory"] = dict(trajectory)
        else:
            body["plan"] = dict(plan or {})
        silence = self.timeout + planning_time(plan)
        return stream(self.session, self.prefix, body, decode=decode_reply, silence=silence,
                      on_event=on_event, cancel=cancel)

    def task(self, task: str | int | Mapping[str, Any], *, execute: bool = False,
             start_tolerance: float = 0.01, move_to_start: bool = False,
             trajectories: bool = True, scene_revision: int | None = None,
             on_change: str = DEFAULT_ON_CHANGE,
             on_planned: Callable[[Mapping[str, Any]], None] | None = None,
             on_event: Callable[[ExecutionEvent], None] | None = None,
             cancel: threading.Event | None = None) -> TaskReply:
        """Plan a task as a whole (every step before anything moves) and, with
        ``execute``, run it on the service's robot (a task without ``start`` starts from
        the robot's state).

        Args:
            task: a name (str) or number (int) of the service's tasks.yaml, or a task
                (``{start, obstacles, steps, ...}``, docs/tasks.md).
            start_tolerance: [rad] largest distance of each joint from the task's start;
                move_to_start: move there first (execute).
            trajectories: include each step's plan in :attr:`TaskReply.steps`.
            scene_revision: plan only in this revision of the kept scene (else
                SceneConflict, ``details.current_revision``); the reply's
                :attr:`TaskReply.scene_revision` names the one used either way.
            on_change: when the kept scene changes while the task moves and a
                remaining step is no longer certified (each checked with what the task
                carries there): ``replan`` (stop, plan the remaining steps from there,
                go on), ``stop`` (stop; the report names the step) or ``ignore``.
            on_planned: called with the planned reply, before the robot moves.
            on_event: called with each execution event (started, progress, finished).
            cancel: set it (from any thread) to stop the arm smoothly (set while the
                task plans, the arm stops as it starts); the reply still comes, with
                the cancelled report.

        Raises:
            InvalidRequest (an unknown task, a step's field), a step's own error
            (``details.step``), ServiceBusy, NotAtStart, a robot's coded error,
            ServiceUnavailable (no reply, or silent for the client's timeout plus the
            task's planning time), MalformedReply.
        """
        body: dict[str, Any] = {"execute": execute, "trajectories": trajectories}
        if isinstance(task, bool):  # a bool is an int: refused here, not as task 0/1
            raise TypeError("task is a name, a number or a task mapping, not a bool")
        if isinstance(task, str):
            body["name"] = task
        elif isinstance(task, int):
            body["number"] = task
        else:
            body["task"] = dict(task)
        if on_change not in ON_CHANGE:
            raise InvalidRequest(f"on_change {on_change!r} must be one of "
                                 f"{', '.join(ON_CHANGE)}", field="on_change")
        if execute:
            body.update(start_tolerance=start_tolerance, move_to_start=move_to_start,
                        on_change=on_change)
        if scene_revision is not None:
            body["scene_revision"] = scene_revision
        steps = body.get("task", {}).get("steps")
        silence = self.timeout + planning_time(body.get("task")) * max(
            1, len(steps) if isinstance(steps, Sequence) else 1)
        end = follow(self.session, self.prefix, f"{self.prefix}/task", body,
                     decode=decode_reply, silence=silence, executes=execute,
                     on_planned=on_planned, on_event=on_event, cancel=cancel)
        if end.planned is None:  # an execution relayed without its plan first
            raise MalformedReply("task", "event", "the stream did not start with 'planned'")
        return TaskReply.parse(end.planned,
                               None if end.finished is None else end.finished.raw)

    # -- the kept planning scene -------------------------------------------------------
    def scene(self) -> SceneReply:
        """The kept planning scene: its revision, objects and carried objects."""
        return SceneReply.parse(self.request("scene"))

    def apply(self, change: Mapping[str, Any] | None = None, *,
              add: Sequence[Mapping[str, Any]] = (), remove: Sequence[str] = (),
              attach: Sequence[Mapping[str, Any]] = (), detach: Sequence[str] = (),
              state: Mapping[str, float] | None = None, clear: bool = False,
              if_revision: int | None = None, apply_id: str | None = None,
              turn: str | None = None) -> SceneApplied:
        """Change the kept scene, all or nothing, in one new revision: ``clear``, then
        ``remove`` (ids), ``add`` (objects, plan_request.json's obstacle form or meshes),
        ``detach`` (ids), ``attach`` (``{object, link, touch_links, mass, com}``), at the
        robot's ``state`` [rad] if given; with ``if_revision`` only if the scene is still
        at that revision. A whole apply request as ``change`` takes the keywords' place
        (they are added to it). ``apply_id`` (default: a new random one, unless
        ``change`` has one) makes a retry safe: the service answers an id it has taken
        with the revision it made (``already_applied``) and changes nothing. ``turn``: the
        token a lost ``if_revision`` race handed this writer (``SceneConflict.details
        ["turn"]``); :meth:`update` does the read-modify-write loop with it.

        Raises:
            SceneConflict (``details.current_revision``), InvalidRequest naming the
            field (``add[3].mesh``, ``remove[0]``), ServiceBusy, ServiceUnavailable.
        """
        body: dict[str, Any] = dict(change or {})
        for k, v in (("add", add), ("remove", remove), ("attach", attach),
                     ("detach", detach)):
            if v:
                body[k] = [*body.get(k, ()), *v]
        if state is not None:
            body["state"] = dict(state)
        if clear:
            body["clear"] = True
        if if_revision is not None:
            body["if_revision"] = if_revision
        if apply_id is not None:
            body["apply_id"] = apply_id
        if turn is not None:
            body["turn"] = turn
        body.setdefault("apply_id", uuid.uuid4().hex)
        return SceneApplied.parse(self.request("scene/apply", body))

    def update(self, make_change: Callable[[SceneReply], Mapping[str, Any] | None], *,
               attempts: int = 50) -> SceneApplied | None:
        """Read the scene, apply ``make_change(scene)`` at that revision, again after each
        lost race with the turn the service hands the loser
        (:func:`arduinobot.client.scene_update.update_scene`)."""
        return update_scene(self, make_change, attempts=attempts)

    # -- seeing (issue 41) ------------------------------------------------------------
    def perceive(self, image: bytes | str | os.PathLike[str] | None = None, *,
                 topic: bool = False, camera: str | None = None,
                 intrinsics: Mapping[str, Any] | None = None,
                 markers: Mapping[str, Any] | None = None,
                 state: Mapping[str, float] | None = None, apply: bool = False,
                 remove_unseen: bool = False) -> PerceiveReply:
        """The objects a camera image shows through their markers, in the world frame
        (``<prefix>/perceive``); with ``apply``, put into the kept scene.

        Args:
            image: a PNG or JPEG, as its bytes or its file's path; or None with ``topic``:
                the latest image of the service's camera topic (``serve --ros2
                --camera-topic``).
            camera: the camera's link (default: the topic image's frame, else the model's
                Gazebo camera sensor's link).
            intrinsics: ``{fx, fy, cx, cy[, width, height, distortion]}`` [px] (default:
                the topic's CameraInfo, else the model's Gazebo sensor's).
            markers: ``{dictionary, size, objects}`` (default: the service's objects.yaml).
            state: the robot's joints [rad] when the image was taken (default: the
                model's initial positions).
            apply: put the seen objects into the kept scene (one seen again moves);
                remove_unseen: also take the map's objects not seen out of it.

        Raises:
            ImageInvalid (not an image, all one colour, no image on the topic yet),
            NoMarker, UnknownMarker, MarkerRefused, InvalidRequest naming the field (an
            unknown camera link, no camera topic), ServiceBusy, ServiceUnavailable.
            FileNotFoundError: ``image`` names no file. TypeError: neither or both of
            ``image`` and ``topic``.
        """
        if (image is None) == (not topic):
            raise TypeError("give exactly one of image and topic=True")
        body: dict[str, Any] = {"apply": apply}
        if topic:
            body["image"] = "topic"
        else:
            data, fmt = _image_bytes(image)
            body["image"] = {"format": fmt, "data": base64.b64encode(data).decode("ascii")}
        for key, value in (("camera", camera), ("intrinsics", intrinsics),
                           ("markers", markers), ("state", state)):
            if value is not None:
                body[key] = dict(value) if isinstance(value, Mapping) else value
        if remove_unseen:
            body["remove_unseen"] = True
        return PerceiveReply.parse(self.request("perceive", body))

    def blend(self, plan: Mapping[str, Any], *, lead: float | None = None
              ) -> dict[str, Any]:
        """Blend the goal of ``plan`` into the motion in progress, planned from its state
        ``lead`` [s] ahead (the service's default, 0.8 s, when None; it must cover the
        planning): ``{"event": "blended", "execution", "tick", "duration"}``.

        Raises:
            TooLate: nothing moves, it stops before the blend could start, or the planning
                took longer than the lead.
        """
        body: dict[str, Any] = {"plan": dict(plan), "blend": True}
        if lead is not None:
            body["blend_lead"] = lead  # the service refuses one outside its range
        return self.request("execute", body,
                            timeout=self.timeout + planning_time(plan))

    def cancel_execution(self, execution: str | None = None) -> str | None:
        """Stop ``execution`` (its id; None: whatever runs) smoothly, from any client; the
        id cancelled, or None if it is not running."""
        return cancel_execution(self.session, self.prefix, execution, decode=decode_reply,
                                timeout=self.timeout)

    def robot_state(self) -> dict[str, Any]:
        """The robot's joint state (``{stamp, name, position, velocity, effort}``)."""
        return self.request("robot_state")

    # these three have no response schema: their replies come as they are
    def health(self, *, instance: str | None = None) -> dict[str, Any]:
        return self.request("health", instance=instance)

    def description(self) -> dict[str, Any]:
        return self.request("description")

    def schema(self) -> dict[str, Any]:
        return self.request("schema")


def _image_bytes(image: bytes | str | os.PathLike[str] | None) -> tuple[bytes, str]:
    """An image's bytes and its format: ``jpeg`` when its bytes start as a JPEG's, else
    ``png`` (the service names what anything else is not)."""
    data = bytes(image) if isinstance(image, (bytes, bytearray)) else \
        Path(os.fspath(image or "")).read_bytes()
    return data, "jpeg" if data.startswith(b"\xff\xd8\xff") else "png"
