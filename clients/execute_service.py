"""Executing trajectories on the service's robot: ``<prefix>/execute`` and friends.

``arduinobot serve`` plugs this into the service (:class:`service.server.ServeOptions`
``extensions``): the service plans, this drives the robot, so the service itself never
imports the drivers.

The keys and their requests are the README's ("Moving the arm"). What it leaves out:
``<p>/execute`` replies on the one query (get it with consolidation NONE) ``{"event":
"started", "execution", "duration"}``, ``{"event": "progress", ...}`` every
:data:`PROGRESS_EVERY` ticks, then ``{"event": "finished", "execution", "report"}``; a
plan without ``start`` starts from the robot's state; ``start_tolerance`` defaults to
0.01 rad. A blend (``"blend": true`` with a ``plan`` while the arm moves) is planned from
the setpoint :data:`BLEND_LEAD` ahead and gets one reply, ``{"event": "blended",
"execution", "tick", "duration"}`` (or ``TOO_LATE``); the running execution's stream goes
on to its final report. Errors as everywhere: ``{"error": {code, message, details}}``.

The robot is MuJoCo's twin by default (built on first use, off Zenoh's callback thread,
so ``serve`` needs MuJoCo only when executing), the real arm with ``serve --serial PORT``
(opened at start, so a missing or busy port fails the start). Nothing here imports
mujoco or serial at import time.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any, Literal

import orjson
import zenoh

from planner.codes import Code
from planner.errors import InvalidRequest, PlanningError
from service import wire
from service.keyguard import addressed_exactly
from service.messages import Failure, Outcome

from .execute import ExecuteOptions, ExecutionBusy, Executor, TooLate, plan_start
from .joint_states import tick_message
from .robots.base import RobotError
from .segments import SampledTrajectory

_log = logging.getLogger(__name__)

JSON = "application/json"
PROGRESS_EVERY = 10  # ticks between progress replies (10 Hz at 100 Hz)
_FIELDS = {"trajectory", "plan", "start_tolerance", "move_to_start", "client", "blend"}
BLEND_LEAD = 0.8  # [s] ahead of the arm a blend is planned for (planning must finish)

# submit(plan request dict, respond(Success | Failure)) -> None: hands a plan job to the
# pool; respond is called once, from a pool thread
SubmitPlan = Callable[[dict[str, Any], Callable[[Outcome], None]], None]


@dataclass(frozen=True)
class RobotSpec:
    """The robot a service drives.

    Attributes:
        kind: ``sim`` (MuJoCo twin), ``serial`` (the real arm) or ``none``.
        port, baud: the serial port (None: the URDF's ros2_control ``port``) and baud.
        rate: control rate [Hz].
        boot_wait: [s] to wait after opening the port (the Arduino resets).
    """

    kind: Literal["sim", "serial", "none"] = "sim"
    port: str | None = None
    baud: int | None = None
    rate: float = 100.0
    boot_wait: float = 2.0

    def open(self, description: Any, *, obstacles: Sequence[Mapping[str, Any]] = ()) -> Any:
        """The driver: the real arm (its port opened) or the twin among ``obstacles``.

        Raises:
            RobotError: kind ``none``, or the port's error (PortNotFound, PortBusy, ...).
        """
        if self.kind == "serial":
            from .robots.serial_arduinobot import SerialArduinobot
            return SerialArduinobot.from_description(description, self.port, baud=self.baud,
                                                     rate=self.rate, boot_wait=self.boot_wait)
        if self.kind == "sim":
            from .robots.sim_arduinobot import SimArduinobot
            return SimArduinobot(description, obstacles=obstacles)
        raise RobotError("this service drives no robot (serve --no-robot)")


def _reply_err(query: zenoh.Query, code: str, message: str,
               details: Mapping[str, Any] | None = None) -> None:
    query.reply_err(wire.encode({"error": {"code": code, "message": message,
                                           "details": dict(details or {})}}), encoding=JSON)


@contextmanager
def _answering(query: zenoh.Query, where: str, internal: str) -> Iterator[None]:
    """A coded error (planner or robot) in the block answers ``query`` as itself; any
    other is logged and answered INTERNAL with the message ``internal``."""
    try:
        yield
    except (PlanningError, RobotError) as e:
        _reply_err(query, e.code, e.message, e.details)
    except Exception:  # noqa: BLE001 -- logged; the querier gets INTERNAL
        _log.exception("%s: %s", where, internal)
        _reply_err(query, Code.INTERNAL, internal)


class ExecuteService:
    """The execute, cancel and robot_state queryables and the joint_states publisher."""

    def __init__(self, session: zenoh.Session, prefix: str, description: Any,
                 spec: RobotSpec, *, submit_plan: SubmitPlan | None = None) -> None:
        self.session, self.prefix, self.description, self.spec = (session, prefix,
                                                                   description, spec)
        self.submit_plan = submit_plan
        self._robot: Any = None
        self._executor: Any = None
        self._robot_lock = threading.Lock()
        self._busy = threading.Lock()
        self._cancel = threading.Event()
        self._current: str | None = None
        self._thread: threading.Thread | None = None
        self._running: Any = None  # the Executor playing now
        self._ids = itertools.count(1)
        self._publisher: Any = None
        self._entities: list[Any] = []  # the publisher, then the queryables

    def start(self) -> None:
        if self.spec.kind == "serial":
            self.robot()  # a missing or busy port fails the start, clearly

        p = self.prefix
        s = self.session
        self._publisher = s.declare_publisher(f"{p}/joint_states", encoding=JSON)
        self._entities.append(self._publisher)
        # execute and robot_state may build the twin (~1.5 s) or wait for the pool: they
        # run on their own threads, never on Zenoh's callback thread
        for key, fn, threaded in ((f"{p}/execute", self._on_execute, True),
                                  (f"{p}/execute/cancel", self._on_cancel, False),
                                  (f"{p}/robot_state", self._on_state, True)):
            self._entities.append(s.declare_queryable(
                key, self._guard(key, fn, threaded=threaded), complete=True))
        _log.info("execute: robot %s%s, %g Hz; keys %s/{execute,execute/cancel,robot_state,"
                  "joint_states}", self.spec.kind,
                  f" on {self.spec.port}" if self.spec.port else "", self.spec.rate, p)

    def close(self) -> None:
        """Stop a running execution smoothly, then release the robot."""
        self._cancel.set()
        if self._thread is not None:
            self._thread.join(10.0)
        for e in reversed(self._entities):
            try:
                e.undeclare()
            except zenoh.ZError as err:  # closing goes on: the session's end drops it too
                _log.warning("undeclaring %s failed: %s", e, err)
        self._entities.clear()
        if self._robot is not None:
            self._robot.close()
            self._robot = None

    # -- the robot ------------------------------------------------------------------------

    def robot(self) -> Any:
        """The driver, built on first use (the twin) or at start (the real arm)."""
        with self._robot_lock:
            if self._robot is None:
                self._robot = self.spec.open(self.description)
                self._executor = Executor.for_description(  # in real time, the twin too
                    self._robot, self.description, options=ExecuteOptions(rate=self.spec.rate))
            return self._robot

    # -- queries --------------------------------------------------------------------------
    def _guard(self, key: str, fn: Callable[[zenoh.Query], None], *, threaded: bool):
        def handle(query: zenoh.Query) -> None:
            with _answering(query, key, "unexpected failure in the service"):
                fn(query)

        def on_query(query: zenoh.Query) -> None:
            if not addressed_exactly(key, query):
                return  # a wildcard must not move the arm (see service.keyguard)
            if threaded:
                threading.Thread(target=handle, args=(query,), daemon=True,
                                 name=key.rsplit("/", 1)[-1]).start()
            else:
                handle(query)
        return on_query

    def _on_state(self, query: zenoh.Query) -> None:
        query.reply(f"{self.prefix}/robot_state", wire.encode(self.robot().state().to_dict()),
                    encoding=JSON)

    def _on_cancel(self, query: zenoh.Query) -> None:
        body = _payload(query, required=False)
        want = body.get("execution") if isinstance(body, dict) else None
        cur = self._current
        hit = cur is not None and (want is None or want == cur)
        if hit:
            _log.info("execution %s: cancel requested", cur)
            self._cancel.set()
        query.reply(f"{self.prefix}/execute/cancel",
                    wire.encode({"cancelled": cur if hit else None}), encoding=JSON)

    def _on_execute(self, query: zenoh.Query) -> None:
        body = _payload(query, required=True)
        if not isinstance(body, dict):
            raise InvalidRequest("must be a JSON object")
        unknown = sorted(set(body) - _FIELDS)
        if unknown:
            raise InvalidRequest(f"unknown field (allowed: {', '.join(sorted(_FIELDS))})",
                                 field=unknown[0])
        if ("trajectory" in body) == ("plan" in body):
            raise InvalidRequest("give exactly one of trajectory and plan")
        tol = body.get("start_tolerance", 0.01)
        if isinstance(tol, bool) or not isinstance(tol, (int, float)) \
                or not (math.isfinite(tol) and 0 < tol <= 1):
            raise InvalidRequest(f"{tol!r} must be in (0, 1] rad", field="start_tolerance")
        for flag in ("move_to_start", "blend"):
            if not isinstance(body.get(flag, False), bool):
                raise InvalidRequest("must be true or false", field=flag)
        client = body.get("client")
        if client is not None and (not isinstance(client, str) or not client.isalnum()):
            raise InvalidRequest("must be an alphanumeric id", field="client")
        robot = self.robot()
        if body.get("blend", False):
            self._blend(query, body)
            return
        if not self._busy.acquire(blocking=False):
            raise ExecutionBusy(f"the robot is executing {self._current}; cancel it first "
                                "(<prefix>/execute/cancel)",
                                details={"execution": self._current})
        try:
            execution = f"x{next(self._ids)}"
            self._current = execution
            self._cancel.clear()
            run = _Run(self, query, execution, float(tol), body.get("move_to_start", False),
                       client)
            if "trajectory" in body:
                run.start_with(body["trajectory"])
                return
            req = dict(body["plan"]) if isinstance(body["plan"], dict) else body["plan"]
            if isinstance(req, dict) and "start" not in req:
                req["start"] = plan_start(robot, self.description)
            self._plan(req, run.on_planned)
        except BaseException:
            self._finish()
            raise

    def _plan(self, request: Any, respond: Callable[[Outcome], None]) -> None:
        """Hand the plan ``request`` to the pool (checked first); ``respond`` gets its outcome."""
        if self.submit_plan is None:
            raise InvalidRequest("this service cannot plan", field="plan")
        self.submit_plan(wire.decode("plan", wire.encode(request)), respond)

    def _blend(self, query: zenoh.Query, body: Mapping[str, Any]) -> None:
        """A new goal for the moving arm: plan from the setpoint ``BLEND_LEAD`` ahead
        (a moving start) and switch to it at that tick; one reply, ``blended`` or an
        error (``TOO_LATE`` when the arm stops first or planning took too long)."""
        if not isinstance(body.get("plan"), dict):
            raise InvalidRequest("a blend needs a plan request (the new goal)", field="plan")
        ex, execution = self._running, self._current
        if ex is None:
            raise TooLate("nothing is moving: send the goal without blend")
        k, q, qd, qdd = ex.lookahead(BLEND_LEAD)
        names = ex.robot.joint_names
        req = {**body["plan"], "start": dict(zip(names, q.tolist())),
               "start_velocity": dict(zip(names, qd.tolist())),
               "start_acceleration": dict(zip(names, qdd.tolist()))}
        key = f"{self.prefix}/execute"

        def on_planned(outcome: Outcome) -> None:
            with _answering(query, key, "the blend failed"):
                if isinstance(outcome, Failure):
                    _reply_err(query, outcome.code, outcome.message, outcome.details)
                else:
                    traj = SampledTrajectory.from_json(orjson.loads(outcome.body))
                    ex.switch(traj, k)
                    query.reply(key, wire.encode({"event": "blended", "execution": execution,
                                                  "tick": k, "duration": traj.duration}),
                                encoding=JSON)
            query.drop()
        self._plan(req, on_planned)

    def _finish(self) -> None:
        self._current = None
        if self._busy.locked():
            self._busy.release()


def _payload(query: zenoh.Query, *, required: bool) -> Any:
    zb = query.payload
    raw = zb.to_bytes() if zb is not None else b""
    if not raw:
        if required:
            raise InvalidRequest("empty payload: send a JSON object")
        return {}
    return wire.parse_json(raw)


class _Run:
    """One execution: its query (replied to until the final report), its thread."""

    def __init__(self, svc: ExecuteService, query: zenoh.Query, execution: str,
                 tolerance: float, move: bool, client: str | None) -> None:
        self.svc, self.query, self.execution = svc, query, execution
        self.tolerance, self.move, self.client = tolerance, move, client
        self.key = f"{svc.prefix}/execute"

    def on_planned(self, outcome: Outcome) -> None:
        if isinstance(outcome, Failure):
            self._fail(outcome.code, outcome.message, outcome.details)
            return
        try:
            self.start_with(orjson.loads(outcome.body))
        except Exception as e:  # noqa: BLE001 -- answered, never swallowed silently
            _log.exception("execution %s: could not start", self.execution)
            self._fail(getattr(e, "code", Code.INTERNAL), str(e), getattr(e, "details", {}))

    def start_with(self, trajectory: Any) -> None:
        traj = SampledTrajectory.from_json(trajectory)  # InvalidTrajectory if it is none
        t = threading.Thread(target=self._run, args=(traj,), name=f"execute-{self.execution}",
                             daemon=True)
        self.svc._thread = t
        t.start()

    def _fail(self, code: str, message: str, details: Mapping[str, Any]) -> None:
        _reply_err(self.query, code, message, details)
        self.query.drop()
        self.svc._finish()

    def _reply(self, body: Mapping[str, Any]) -> None:
        self.query.reply(self.key, json.dumps(body).encode(), encoding=JSON)

    def _run(self, traj: Any) -> None:
        svc = self.svc
        watch = None
        with _answering(self.query, f"execution {self.execution}", "the execution failed"):
            try:
                if self.client is not None:
                    watch = self._watch_client()
                base = svc._executor
                pub = svc._publisher

                def on_tick(tick: Any) -> None:
                    msg = tick_message(tick)
                    pub.put(json.dumps(msg).encode())
                    if tick.index % PROGRESS_EVERY == 0:
                        self._reply({"event": "progress", "execution": self.execution,
                                     "time": tick.time, **msg})
                ex = Executor(base.robot, base.limits, torques=base.torques, on_tick=on_tick,
                              options=replace(base.options, start_tolerance=self.tolerance,
                                              move_to_start=self.move))
                ex.check_start(traj)  # refuse before telling the client it started
                svc._running = ex
                self._reply({"event": "started", "execution": self.execution,
                             "duration": traj.duration, "joint_names": list(traj.joint_names)})
                t0 = time.monotonic()
                report = ex.execute(traj, cancel=svc._cancel)
                if watch is not None:  # done: the client may leave now
                    watch.undeclare()
                    watch = None
                _log.info("execution %s %s after %.3f s", self.execution, report.outcome,
                          time.monotonic() - t0)
                self._reply({"event": "finished", "execution": self.execution,
                             "report": report.to_dict()})
            finally:
                svc._running = None
                if watch is not None:
                    watch.undeclare()
                svc._finish()
        self.query.drop()

    def _watch_client(self) -> Any:
        """Cancel when the client's liveliness token goes (the client died or lost the
        network); refuse if it is not there to begin with."""
        key = f"{self.svc.prefix}/execute/client/{self.client}"
        if not any(r.ok is not None for r in self.svc.session.liveliness().get(key,
                                                                               timeout=2.0)):
            raise InvalidRequest(f"no liveliness token {key}: declare it before executing",
                                 field="client")
        cancel, execution = self.svc._cancel, self.execution

        def on_change(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.DELETE:
                _log.warning("execution %s: client %s lost, stopping", execution, key)
                cancel.set()
        return self.svc.session.liveliness().declare_subscriber(key, on_change)


def execute_extension(spec: RobotSpec) -> Callable[..., ExecuteService]:
    """A :class:`service.server.ServeOptions` extension serving ``<prefix>/execute`` on
    the robot ``spec`` describes (started once the service's session is open)."""
    def make(session: zenoh.Session, prefix: str, description: Any,
             submit_plan: SubmitPlan) -> ExecuteService:
        svc = ExecuteService(session, prefix, description, spec, submit_plan=submit_plan)
        svc.start()
        return svc
    return make
