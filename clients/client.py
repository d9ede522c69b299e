"""The Python client of the arduinobot service.

    from clients.client import PlannerClient
    with PlannerClient() as c:                      # tcp/127.0.0.1:7447
        res = c.plan({"goal": {"named": "reach_forward"}})
        print(res.duration, res.positions.shape)

Every service error raises its own class (:mod:`clients.errors`); no reply at all raises
:class:`~clients.errors.ServiceUnavailable` with a hint (and says when the connection
itself is down, e.g. a router restarting). With ``spread=True`` each request goes to the
least loaded live instance (:mod:`clients.balance`: liveliness on ``<prefix>/alive/*``,
load on ``/health``), by its own key, and on to another one if that instance has gone or
is BUSY.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import orjson
import zenoh

from service.zconfig import DEFAULT_ENDPOINT, DEFAULT_PREFIX, zenoh_config

from .balance import LoadBalancer
from .errors import ServiceBusy, ServiceUnavailable, error_from_reply

_log = logging.getLogger(__name__)

_HINT = ("start one with `arduinobot serve` (or `./dev arduinobot serve`), or check the "
         "endpoint (--connect) and the prefix")


@dataclass(frozen=True)
class TrajectoryPoint:
    positions: tuple[float, ...]        # [rad]
    velocities: tuple[float, ...]       # [rad/s]
    accelerations: tuple[float, ...]    # [rad/s^2]
    effort: tuple[float, ...]           # [N m]
    time_from_start: float              # [s]


@dataclass(frozen=True)
class PlanResult:
    """A planned trajectory of the actuated joints.

    Attributes:
        joint_names: column order of every array.
        points: the samples; ``times``/``positions``/... give them as arrays, shape (m, dof).
        duration: [s]. path: collision-checked waypoints, shape (k, dof) [rad].
        timing: seconds per stage. verification: the service's verification report.
        raw: the reply as received.
    """

    joint_names: tuple[str, ...]
    points: tuple[TrajectoryPoint, ...]
    duration: float
    path: np.ndarray
    timing: Mapping[str, float]
    verification: Mapping[str, Any]
    planner: str
    request_id: str
    raw: Mapping[str, Any]

    @classmethod
    def from_json(cls, body: Mapping[str, Any]) -> PlanResult:
        t = body["trajectory"]
        pts = tuple(TrajectoryPoint(tuple(p["positions"]), tuple(p["velocities"]),
                                    tuple(p["accelerations"]), tuple(p["effort"]),
                                    float(p["time_from_start"])) for p in t["points"])
        return cls(tuple(t["joint_names"]), pts, float(body["duration"]),
                   np.array(body["path"], float).reshape(-1, len(t["joint_names"])),
                   dict(body["timing"]), dict(body["verification"]),
                   str(body.get("planner", "")), str(body.get("request_id", "")), body)

    def to_csv(self) -> str:
        """One row per sample: time_from_start, then position, velocity, acceleration and
        effort of each joint (``<joint>.position``, ...)."""
        header = ["time_from_start"] + [f"{n}.{kind}" for kind in
                                        ("position", "velocity", "acceleration", "effort")
                                        for n in self.joint_names]
        rows = [",".join(header)]
        for p in self.points:
            vals = (p.time_from_start, *p.positions, *p.velocities, *p.accelerations,
                    *p.effort)
            rows.append(",".join(repr(float(v)) for v in vals))
        return "\n".join(rows) + "\n"

    def _arr(self, attr: str) -> np.ndarray:
        return np.array([getattr(p, attr) for p in self.points], float)

    @property
    def times(self) -> np.ndarray:
        return np.array([p.time_from_start for p in self.points], float)

    @property
    def positions(self) -> np.ndarray:
        return self._arr("positions")

    @property
    def velocities(self) -> np.ndarray:
        return self._arr("velocities")

    @property
    def accelerations(self) -> np.ndarray:
        return self._arr("accelerations")

    @property
    def efforts(self) -> np.ndarray:
        return self._arr("effort")


@dataclass(frozen=True)
class Pose:
    xyz: tuple[float, float, float]     # [m]
    rpy: tuple[float, float, float]     # [rad]
    matrix: np.ndarray                  # shape (4, 4)


@dataclass(frozen=True)
class FkResult:
    joints: Mapping[str, float]
    links: Mapping[str, Pose]
    tcp: tuple[float, float, float] | None
    request_id: str


@dataclass(frozen=True)
class IkSolution:
    joints: Mapping[str, float]
    branch: str


@dataclass(frozen=True)
class StateCheckResult:
    """``valid`` and every colliding ``pairs``; ``clearance`` [m] to the ``closest`` pair."""

    valid: bool
    pairs: tuple[tuple[str, str], ...]
    clearance: float | None
    closest: tuple[str, str] | None
    joints: Mapping[str, float]
    request_id: str


class PlannerClient:
    """A Zenoh session to the arduinobot service.

    Args:
        endpoints: where to connect (a service listening, or a router).
        prefix: the service's key prefix.
        timeout: seconds to wait for a reply (plans add their planning_time).
        mode: the client's Zenoh mode (``client`` needs a reachable endpoint).
        config_file: a zenoh JSON5 config (TLS, credentials); options here override it.
        spread: send each request to the least loaded live instance, and to another
            one if it has gone or is BUSY (see :mod:`clients.balance`).

    Raises:
        ServiceUnavailable: ``reason="connect_failed"`` if no session could be opened.
    """

    def __init__(self, endpoints: Sequence[str] | str = (DEFAULT_ENDPOINT,), *,
                 prefix: str = DEFAULT_PREFIX, timeout: float = 60.0,
                 mode: Literal["client", "peer"] = "client", config_file: str | Path | None = None,
                 spread: bool = False) -> None:
        self.endpoints = [endpoints] if isinstance(endpoints, str) else list(endpoints)
        self.prefix, self.timeout, self.spread = prefix, float(timeout), spread
        try:
            self.session = zenoh.open(zenoh_config(mode=mode, connect=self.endpoints,
                                                   listen=[] if mode == "client" else None,
                                                   config_file=config_file))
        except zenoh.ZError as e:
            raise ServiceUnavailable(
                f"cannot reach {', '.join(self.endpoints)}: {e}; {_HINT}",
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

        Raises:
            ServiceError subclasses for error replies; ServiceUnavailable for none.
        """
        if isinstance(body, Mapping):
            payload: bytes | None = json.dumps(body, allow_nan=False).encode()
        elif isinstance(body, str):
            payload = body.encode()
        else:
            payload = body
        wait = self.timeout if timeout is None else float(timeout)
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
        return _decode(replies[0], key, wait)

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
                return _decode(replies[0], key, wait)
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
        return list(self.session.get(key, payload=payload, timeout=wait,
                                     encoding="application/json" if payload else None))

    def plan(self, request: Mapping[str, Any] | None = None, *,
             instance: str | None = None, **fields: Any) -> PlanResult:
        """Plan: a whole v1 request, or its fields as keywords (``goal={"named": "home"}``).

        Raises:
            InvalidRequest, StartInCollision, GoalInCollision, GoalOutOfReach, NoPathFound,
            TrajectoryFailed, RequestTimeout, ServiceBusy, InternalError, ServiceUnavailable.
        """
        req = {**(request or {}), **fields}
        wait = self.timeout + _planning_time(req)
        return PlanResult.from_json(self.request("plan", req, instance=instance,
                                                 timeout=wait))

    def fk(self, joints: Mapping[str, float] | None = None, *,
           links: Sequence[str] | None = None) -> FkResult:
        """Link poses at ``joints`` [rad] (missing joints are 0)."""
        req: dict[str, Any] = {"joints": dict(joints or {})}
        if links is not None:
            req["links"] = list(links)
        b = self.request("fk", req)
        links = {k: Pose(tuple(v["xyz"]), tuple(v["rpy"]), np.array(v["matrix"]))
                 for k, v in b["links"].items()}
        return FkResult(b["joints"], links,
                        None if b.get("tcp") is None else tuple(b["tcp"]), b["request_id"])

    def ik(self, position: Sequence[float]) -> tuple[IkSolution, ...]:
        """Every IK branch putting the tcp at ``position`` [m] (GoalOutOfReach if none)."""
        b = self.request("ik", {"position": [float(v) for v in position]})
        return tuple(IkSolution(s["joints"], s["branch"]) for s in b["solutions"])

    def check_state(self, joints: Mapping[str, float] | None = None, *,
                    obstacles: Sequence[Mapping[str, Any]] = (),
                    padding: float = 0.0) -> StateCheckResult:
        """Whether a state is collision-free among ``obstacles``, with clearance [m]."""
        req: dict[str, Any] = {"joints": dict(joints or {})}
        if obstacles:
            req["obstacles"] = list(obstacles)
        if padding:
            req["padding"] = padding
        b = self.request("check", req)
        return StateCheckResult(bool(b["valid"]), tuple(tuple(p) for p in b["pairs"]),
                                b.get("clearance"),
                                None if b.get("closest") is None else tuple(b["closest"]),
                                b["joints"], b["request_id"])

    def health(self, *, instance: str | None = None) -> dict[str, Any]:
        return self.request("health", instance=instance)

    def description(self) -> dict[str, Any]:
        return self.request("description")

    def schema(self) -> dict[str, Any]:
        return self.request("schema")


def _planning_time(req: Mapping[str, Any]) -> float:
    v = req.get("planning_time", 1.0)
    return float(v) if isinstance(v, (int, float)) and 0 < v <= 60 else 1.0


def _decode(reply: zenoh.Reply, key: str, wait: float) -> dict[str, Any]:
    if reply.ok is not None:
        return orjson.loads(reply.ok.payload.to_bytes())  # strict JSON, ~3x json's speed
    err = reply.err
    text = err.payload.to_bytes().decode("utf-8", "replace")
    if str(err.encoding).startswith("application/json"):
        try:
            body = json.loads(text)
        except json.JSONDecodeError:
            body = None
        if isinstance(body, dict) and "error" in body:
            raise error_from_reply(body)
    if text == "Timeout":
        raise ServiceUnavailable(
            f"'{key}': a service took the query but sent no reply within {wait:g} s "
            "(overloaded, or a long request: raise the timeout)", reason="timeout",
            details={"key": key, "timeout": wait})
    raise ServiceUnavailable(f"'{key}': Zenoh answered with an error: {text}",
                             reason="zenoh_error", details={"key": key, "zenoh": text})
