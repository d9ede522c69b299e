"""Executing trajectories on the service's robot: ``<prefix>/execute`` and friends.

``arduinobot serve`` plugs this into the service (:class:`service.server.ServeOptions`
``extensions``): the service plans, :mod:`execution` drives the robot, as the service's
workers use the planner.

The keys and their requests are the README's ("Moving the arm"); a request is checked
against ``service/schema/execute_request.json`` by :func:`service.wire.decode`, as every
other request is. ``<p>/execute`` replies on the one query (get it with consolidation
NONE) ``{"event": "started", "execution", "duration"}``, ``{"event": "progress", ...}``
every :data:`PROGRESS_EVERY` ticks, then ``{"event": "finished", "execution", "report"}``;
a plan without ``start`` starts from the robot's state; ``start_tolerance`` defaults to
0.01 rad. A blend (``"blend": true`` with a ``plan`` while the arm moves) is planned from
the setpoint :data:`BLEND_LEAD` ahead and gets one reply, ``{"event": "blended",
"execution", "tick", "duration"}`` (or ``TOO_LATE``); the running execution's stream goes
on to its final report. Errors as everywhere: ``{"error": {code, message, details}}``;
a driver that fails mid-motion (the port unplugged, a write that stalls) ends the stream
with its coded error, whose details hold the last setpoint the arm took, and the next
request opens the port afresh.

The robot is MuJoCo's twin by default (built on first use, off Zenoh's callback thread,
so ``serve`` needs MuJoCo only when executing), the real arm with ``serve --serial PORT``
(opened at start, so a missing or busy port fails the start).
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any, Protocol

import orjson
import zenoh

from description import Description
from execution.executor import ExecuteOptions, ExecutionBusy, Executor, TooLate, plan_start
from execution.joint_states import tick_message
from execution.report import Tick
from execution.robots.base import PortError, Robot, RobotError
from execution.robots.spec import RobotSpec
from execution.segments import SampledTrajectory, check_fits
from planner.codes import Code
from planner.errors import InvalidRequest, PlanningError

from . import wire
from .keyguard import addressed_exactly
from .messages import Failure, Outcome

_log = logging.getLogger(__name__)

JSON = "application/json"
PROGRESS_EVERY = 10  # ticks between progress replies (10 Hz at 100 Hz)
BLEND_LEAD = 0.8  # [s] ahead of the arm a blend is planned for (planning must finish)
DEFAULT_START_TOLERANCE = 0.01  # [rad]

# submit(plan request dict, respond(Success | Failure)) -> None: hands a plan job to the
# pool; respond is called once, from a pool thread
SubmitPlan = Callable[[dict[str, Any], Callable[[Outcome], None]], None]


class TickSink(Protocol):
    """Another consumer of each execution tick (``serve --ros2``'s /joint_states: a
    ``ros2.JointStates``), called on the executor's thread; closed with the service."""

    def __call__(self, tick: Tick) -> None: ...

    def close(self) -> None: ...


# open(session, description) -> TickSink: built once the service's session is open
OpenTickSink = Callable[[zenoh.Session, Description], TickSink]


@dataclass(frozen=True)
class ExecuteRequest:
    """A decoded ``<prefix>/execute`` request (see the schema): exactly one of
    ``trajectory`` (a plan reply or ``{joint_names, points}``) and ``plan`` (a v1 plan
    request)."""

    trajectory: Mapping[str, Any] | None
    plan: Mapping[str, Any] | None
    start_tolerance: float
    move_to_start: bool
    blend: bool
    client: str | None
    twin: Mapping[str, Any] | None = None  # a task's objects for a twin (the schema's)

    @classmethod
    def decode(cls, payload: bytes) -> ExecuteRequest:
        """Raises: InvalidRequest naming the field (the schema's refusal)."""
        body = wire.decode("execute", payload)
        return cls(body.get("trajectory"), body.get("plan"),
                   float(body.get("start_tolerance", DEFAULT_START_TOLERANCE)),
                   bool(body.get("move_to_start", False)), bool(body.get("blend", False)),
                   body.get("client"), body.get("twin"))


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

    def __init__(self, session: zenoh.Session, prefix: str, description: Description,
                 spec: RobotSpec, *, submit_plan: SubmitPlan | None = None,
                 tick_sink: TickSink | None = None) -> None:
        self.session, self.prefix, self.description, self.spec = (session, prefix,
                                                                   description, spec)
        self.submit_plan = submit_plan
        self.tick_sink = tick_sink
        self._sink_failed = False  # logged once: a failing sink never stops the arm
        self._robot: Robot | None = None
        self._executor: Executor | None = None
        self._robot_lock = threading.Lock()
        self._busy = threading.Lock()
        self._cancel = threading.Event()
        self._current: str | None = None
        self._thread: threading.Thread | None = None
        self._running: Executor | None = None  # the Executor playing now
        self._ids = itertools.count(1)
        self._publisher: zenoh.Publisher | None = None
        self._entities: list[zenoh.Publisher | zenoh.Queryable] = []
        #: the kept scene now (the server sets it): a twin takes its objects and carried
        #: objects before each execution (SimArduinobot.set_scene)
        self.scene_source: Callable[[], Any] | None = None
        self._twin_scene: Any = (0, b"[]")  # (revision, own obstacles) the twin holds

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
        self.drop_robot()
        if self.tick_sink is not None:
            try:
                self.tick_sink.close()
            except Exception:  # noqa: BLE001 -- closing goes on; the session ends it too
                _log.exception("closing the tick sink failed")
            self.tick_sink = None

    def _to_sink(self, tick: Tick) -> None:
        """Hand ``tick`` to the sink; its failure is logged (once) and never reaches the
        executor: /joint_states for RViz must not stop the arm."""
        sink = self.tick_sink
        if sink is None:
            return
        try:
            sink(tick)
        except Exception:  # noqa: BLE001 -- logged; the motion goes on
            if not self._sink_failed:
                self._sink_failed = True
                _log.exception("publishing a tick failed (further failures not logged)")

    # -- the robot ------------------------------------------------------------------------

    def executor(self) -> Executor:
        """The robot's executor, the robot opened on first use (the twin) or at start (the
        real arm), or again after its port failed."""
        with self._robot_lock:
            if self._executor is None:
                self._robot = self.spec.open(self.description)
                self._executor = Executor.for_description(  # in real time, the twin too
                    self._robot, self.description, options=ExecuteOptions(rate=self.spec.rate))
            return self._executor

    def robot(self) -> Robot:
        return self.executor().robot

    def drop_robot(self) -> None:
        """Release the robot (after its port failed: the next request opens it again)."""
        with self._robot_lock:
            if self._robot is not None:
                try:
                    self._robot.close()
                except OSError as e:  # a vanished port may not close cleanly: it is gone
                    _log.warning("closing the robot: %s", e)
            self._robot, self._executor = None, None

    # -- queries --------------------------------------------------------------------------
    def _guard(self, key: str, fn: Callable[[zenoh.Query], None], *, threaded: bool
               ) -> Callable[[zenoh.Query], None]:
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
        raw = _payload(query)
        body = wire.parse_json(raw) if raw else {}
        want = body.get("execution") if isinstance(body, dict) else None
        cur = self._current
        hit = cur is not None and (want is None or want == cur)
        if hit:
            _log.info("execution %s: cancel requested", cur)
            self._cancel.set()
        query.reply(f"{self.prefix}/execute/cancel",
                    wire.encode({"cancelled": cur if hit else None}), encoding=JSON)

    def _on_execute(self, query: zenoh.Query) -> None:
        req = ExecuteRequest.decode(_payload(query))
        robot = self.robot()
        if req.blend:
            self._blend(query, req)
            return
        if not self._busy.acquire(blocking=False):
            raise ExecutionBusy(f"the robot is executing {self._current}; cancel it first "
                                "(<prefix>/execute/cancel)",
                                details={"execution": self._current})
        try:
            execution = f"x{next(self._ids)}"
            self._current = execution
            self._cancel.clear()
            run = _Run(self, query, execution, req)
            self._scene_to_twin(robot, (req.plan or {}).get("obstacles") or (), req.twin)
            if req.trajectory is not None:
                run.start_with(SampledTrajectory.from_json(req.trajectory))
                return
            plan = dict(req.plan or {})
            if "start" not in plan:
                plan["start"] = plan_start(robot, self.description)
            self._plan(plan, run.on_planned)
        except BaseException:
            self._finish()
            raise

    def _scene_to_twin(self, robot: Robot, own: Sequence[Mapping[str, Any]],
                       twin: Mapping[str, Any] | None = None) -> None:
        """Give a twin (a robot with ``set_scene``) the kept scene's objects, the plan's
        own obstacles and the carried objects, when they changed since the last time; a
        task's ``twin`` (its obstacles, the kept scene's among them, and the objects it
        picks up as loose bodies, put back where it has them) instead of the plan's."""
        set_scene = getattr(robot, "set_scene", None)
        snap = self.scene_source() if self.scene_source is not None else None
        if set_scene is None:
            return
        if twin is not None:
            own = twin.get("obstacles") or ()
        key = (getattr(snap, "revision", 0), wire.encode(list(own)), twin is not None)
        # a task's objects start where its scene has them: rebuilt for every task
        if key == self._twin_scene and twin is None:
            return
        if twin is None:
            set_scene([*getattr(snap, "obstacles", ()), *own], getattr(snap, "attached", ()))
        else:
            from planner.scene import AttachedObject
            loose = [AttachedObject.from_mapping(o, where=f"twin.objects[{i}]")
                     for i, o in enumerate(twin.get("objects") or ())]
            mine = {o["id"] for o in own} | {a.id for a in loose}
            kept = [o for o in getattr(snap, "obstacles", ()) if o.id not in mine]
            set_scene([*kept, *own], getattr(snap, "attached", ()), loose=loose)
        self._twin_scene = key

    def _plan(self, request: Mapping[str, Any], respond: Callable[[Outcome], None]) -> None:
        """Hand the plan ``request`` to the pool (checked first); ``respond`` gets its outcome."""
        if self.submit_plan is None:
            raise InvalidRequest("this service cannot plan", field="plan")
        self.submit_plan(wire.decode("plan", wire.encode(request)), respond)

    def _blend(self, query: zenoh.Query, req: ExecuteRequest) -> None:
        """A new goal for the moving arm: plan from the setpoint ``BLEND_LEAD`` ahead
        (a moving start) and switch to it at that tick; one reply, ``blended`` or an
        error (``TOO_LATE`` when the arm stops first or planning took too long)."""
        if req.plan is None:
            raise InvalidRequest("a blend needs a plan request (the new goal)", field="plan")
        ex, execution = self._running, self._current
        if ex is None:
            raise TooLate("nothing is moving: send the goal without blend")
        k, q, qd, qdd = ex.lookahead(BLEND_LEAD)
        names = ex.robot.joint_names
        plan = {**req.plan, "start": dict(zip(names, q.tolist())),
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
        self._plan(plan, on_planned)

    def _finish(self) -> None:
        self._current = None
        if self._busy.locked():
            self._busy.release()


def _payload(query: zenoh.Query) -> bytes:
    zb = query.payload
    return zb.to_bytes() if zb is not None else b""


class _Run:
    """One execution: its query (replied to until the final report), its thread."""

    def __init__(self, svc: ExecuteService, query: zenoh.Query, execution: str,
                 req: ExecuteRequest) -> None:
        self.svc, self.query, self.execution, self.req = svc, query, execution, req
        self.key = f"{svc.prefix}/execute"

    def on_planned(self, outcome: Outcome) -> None:
        if isinstance(outcome, Failure):
            self._fail(outcome.code, outcome.message, outcome.details)
            return
        try:
            self.start_with(SampledTrajectory.from_json(orjson.loads(outcome.body)))
        except RobotError as e:
            self._fail(e.code, e.message, e.details)
        except Exception as e:  # noqa: BLE001 -- answered, never swallowed silently
            _log.exception("execution %s: could not start", self.execution)
            self._fail(Code.INTERNAL, str(e), {})

    def start_with(self, traj: SampledTrajectory) -> None:
        t = threading.Thread(target=self._run, args=(traj,), name=f"execute-{self.execution}",
                             daemon=True)
        self.svc._thread = t
        t.start()

    def _fail(self, code: str, message: str, details: Mapping[str, Any]) -> None:
        _reply_err(self.query, code, message, details)
        self.query.drop()
        self.svc._finish()

    def _reply(self, body: Mapping[str, Any]) -> None:
        self.query.reply(self.key, wire.encode(body), encoding=JSON)

    def _executor(self) -> Executor:
        """An executor for this run: the robot's, with the request's start options, that
        publishes joint_states and replies progress."""
        base, pub = self.svc.executor(), self.svc._publisher

        grasps = (self.req.twin or {}).get("grasps") or ()
        grip = None
        if grasps:  # a twin grips a task's objects (a real arm has no weld to switch)
            from execution.robots.sim_arduinobot import SimArduinobot, grasp_schedule
            if isinstance(base.robot, SimArduinobot):
                grip = grasp_schedule(base.robot, [(float(g["time"]), g["object"], g["hold"])
                                                   for g in grasps])

        def on_tick(tick: Tick) -> None:
            if grip is not None:
                grip(tick)
            msg = tick_message(tick)
            if pub is not None:
                pub.put(wire.encode(msg))
            self.svc._to_sink(tick)
            if tick.index % PROGRESS_EVERY == 0:
                self._reply({"event": "progress", "execution": self.execution,
                             "time": tick.time, **msg})
        return Executor(base.robot, base.limits, torques=base.torques, on_tick=on_tick,
                        options=replace(base.options,
                                        start_tolerance=self.req.start_tolerance,
                                        move_to_start=self.req.move_to_start))

    def _run(self, traj: SampledTrajectory) -> None:
        svc = self.svc
        watch = None
        with _answering(self.query, f"execution {self.execution}", "the execution failed"):
            try:
                if self.req.client is not None:
                    watch = self._watch_client(self.req.client)
                ex = self._executor()
                check_fits(traj, svc.description)  # a plan for another robot: refused
                ex.check_start(traj)  # refuse before telling the client it started
                svc._running = ex
                self._reply({"event": "started", "execution": self.execution,
                             "duration": traj.duration, "joint_names": list(traj.joint_names)})
                t0 = time.monotonic()
                try:
                    report = ex.execute(traj, cancel=svc._cancel)
                except PortError:
                    svc.drop_robot()  # unplugged or stalled: the next request reopens it
                    raise
                if watch is not None:  # done: the client may leave now
                    watch.undeclare()
                    watch = None
                _log.info("execution %s %s after %.3f s", self.execution, report.outcome,
                          time.monotonic() - t0)
                done: dict[str, Any] = {"event": "finished", "execution": self.execution,
                                        "report": report.to_dict()}
                objects = (self.req.twin or {}).get("objects") or ()
                if objects and hasattr(ex.robot, "object_pose"):
                    # where the twin's objects ended: MuJoCo's state, not the plan's
                    done["objects"] = {o["object"]["id"]: ex.robot.object_pose(
                        o["object"]["id"])[:3, 3].tolist() for o in objects}
                self._reply(done)
            finally:
                svc._running = None
                if watch is not None:
                    watch.undeclare()
                svc._finish()
        self.query.drop()

    def _watch_client(self, client: str) -> zenoh.Subscriber:
        """Cancel when the client's liveliness token goes (the client died or lost the
        network); refuse if it is not there to begin with."""
        key = f"{self.svc.prefix}/execute/client/{client}"
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


def execute_extension(spec: RobotSpec, *, tick_sink: OpenTickSink | None = None
                      ) -> Callable[..., ExecuteService]:
    """A :class:`service.server.ServeOptions` extension serving ``<prefix>/execute`` on
    the robot ``spec`` describes (started once the service's session is open);
    ``tick_sink(session, description)`` opens another consumer of every tick (``serve
    --ros2``'s /joint_states), closed with the service."""
    def make(session: zenoh.Session, prefix: str, description: Description,
             submit_plan: SubmitPlan) -> ExecuteService:
        sink = tick_sink(session, description) if tick_sink is not None else None
        svc = ExecuteService(session, prefix, description, spec, submit_plan=submit_plan,
                             tick_sink=sink)
        try:
            svc.start()
        except BaseException:
            svc.close()
            raise
        return svc
    return make
