"""Executing trajectories on the service's robot: ``<prefix>/execute`` and friends.

``arduinobot serve`` plugs this into the service (:class:`arduinobot.service.server.ServeOptions`
``extensions``): the service plans, :mod:`execution` drives the robot, as the service's
workers use the planner.

The keys and their requests are the README's ("Moving the arm"); a request is checked
against ``src/arduinobot/contract/schema/execute_request.json`` by :func:`arduinobot.contract.wire.decode`, as every
other request is. ``<p>/execute`` replies on the one query (get it with consolidation
NONE) ``{"event": "started", "execution", "duration"}``, ``{"event": "progress", ...}``
every :data:`arduinobot.service.execute.run.PROGRESS_EVERY` ticks, then ``{"event": "finished", "execution", "report"}``;
a plan without ``start`` starts from the robot's state; ``start_tolerance`` defaults to
0.01 rad. While it moves, every kept-scene change re-checks the rest of the motion and,
by the request's ``on_change``, stops it, replans it or lets it go on
(:mod:`arduinobot.service.execute.react`; events ``changed``, ``stopped``, ``replanned``). A blend (``"blend": true`` with a ``plan`` while the arm moves) is planned from
the setpoint ``blend_lead`` (default 0.8 s) ahead and gets one reply, ``{"event": "blended",
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
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.execution.executor import (
    ExecuteOptions,
    ExecutionBusy,
    Executor,
    TooLate,
    plan_start,
)
from arduinobot.execution.joint_states import tick_message
from arduinobot.execution.report import Tick
from arduinobot.execution.robots.base import JointState, Robot
from arduinobot.execution.robots.spec import RobotSpec, twin_start
from arduinobot.execution.segments import SampledTrajectory
from arduinobot.service.execute.io import CODED, ExecuteRequest, payload_of
from arduinobot.service.execute.react import Reactor
from arduinobot.service.execute.run import Run
from arduinobot.service.execute.twin_scene import TwinScene
from arduinobot.service.extension import Host
from arduinobot.service.messages import Failure, Outcome, Submit, SubmitPlan
from arduinobot.service.queries import answering, guarded, reply_failure

if TYPE_CHECKING:
    from arduinobot.scene.state import SceneSnapshot

_log = logging.getLogger(__name__)


class TickSink(Protocol):
    """Another consumer of each execution tick (``serve --ros2``'s /joint_states: a
    ``arduinobot.ros2.JointStates``), called on the executor's thread; closed with the service."""

    def __call__(self, tick: Tick) -> None: ...

    def close(self) -> None: ...


# open(session, description) -> TickSink: built once the service's session is open
OpenTickSink = Callable[[zenoh.Session, Description], TickSink]


class ExecuteService:
    """The execute, cancel and robot_state queryables and the joint_states publisher."""

    def __init__(self, session: zenoh.Session, prefix: str, description: Description,
                 spec: RobotSpec, *, submit_plan: SubmitPlan | None = None,
                 submit: Submit | None = None,
                 tick_sink: TickSink | None = None,
                 scene_source: Callable[[], SceneSnapshot | None] | None = None) -> None:
        self.session, self.prefix, self.description, self.spec = (session, prefix,
                                                                   description, spec)
        self.submit_plan = submit_plan
        self.submit = submit  # the rechecks of a moving arm's rest (:mod:`.react`)
        self.reactor: Reactor | None = None  # the running execution's
        self.tick_sink = tick_sink
        self._sink_failed = False  # logged once: a failing sink never stops the arm
        self._robot: Robot | None = None
        self._executor: Executor | None = None
        self._robot_lock = threading.Lock()
        self._busy = threading.Lock()
        self.cancel = threading.Event()  # set: the running execution stops smoothly
        self._current: str | None = None
        self.thread: threading.Thread | None = None
        self.running: Executor | None = None  # the Executor playing now
        self._ids = itertools.count(1)
        self._publisher: zenoh.Publisher | None = None
        self._entities: list[zenoh.Publisher | zenoh.Queryable | zenoh.Subscriber] = []
        #: the kept scene now (the host's): a twin takes its objects and carried
        #: objects before each execution (SimArduinobot.set_scene)
        self.scene_source = scene_source
        self.twin_scene = TwinScene()  # what the twin holds of it

    def start(self) -> None:
        if self.spec.kind in ("serial", "driver"):
            self.robot()  # a missing or busy port, a bad driver fail the start, clearly

        p = self.prefix
        s = self.session
        self._publisher = s.declare_publisher(f"{p}/joint_states", encoding=wire.JSON)
        self._entities.append(self._publisher)
        # the kept scene's changes: a moving arm's rest is checked again (:mod:`.react`)
        self._entities.append(s.declare_subscriber(f"{p}/scene/changes", self._on_change))
        # execute builds the twin on first use (seconds on CAD meshes) or waits for the
        # pool, robot_state may wait for a port: on their own threads, never on Zenoh's
        for key, fn, threaded in ((f"{p}/execute", self._on_execute, True),
                                  (f"{p}/execute/cancel", self._on_cancel, False),
                                  (f"{p}/robot_state", self._on_state, True)):
            self._entities.append(s.declare_queryable(
                key, self._guard(key, fn, threaded=threaded), complete=True))
        _log.info("execute: robot %s%s, %g Hz; keys %s/{execute,execute/cancel,robot_state,"
                  "joint_states}", self.spec.driver or self.spec.kind,
                  f" on {self.spec.port}" if self.spec.port else "", self.spec.rate, p)

    def close(self) -> None:
        """Stop a running execution smoothly, then release the robot."""
        self.cancel.set()
        if self.thread is not None:
            self.thread.join(10.0)
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

    def publish_tick(self, tick: Tick) -> dict[str, Any]:
        """Publish ``tick`` on ``<prefix>/joint_states`` and hand it to the sink; its
        message. The sink's failure is logged (once) and never reaches the executor:
        /joint_states for RViz must not stop the arm."""
        msg = tick_message(tick)
        if self._publisher is not None:
            self._publisher.put(wire.encode(msg))
        sink = self.tick_sink
        if sink is None:
            return msg
        try:
            sink(tick)
        except Exception:  # noqa: BLE001 -- logged; the motion goes on
            if not self._sink_failed:
                self._sink_failed = True
                _log.exception("publishing a tick failed (further failures not logged)")
        return msg

    # -- the robot ------------------------------------------------------------------------

    def executor(self) -> Executor:
        """The robot's executor, the robot opened on first use (the twin) or at start (the
        real arm), or again after its port failed."""
        with self._robot_lock:
            if self._executor is None:
                self._robot = self.spec.open(self.description)
                self._executor = Executor.for_description(  # in real time, the twin too
                    self._robot, self.description, options=ExecuteOptions(rate=self.spec.rate))
                # a stop (a cancel, a scene change) must not wait for its first choice
                self._executor.warm_stops()
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
        # exact: a wildcard must not move the arm (see arduinobot.service.keyguard)
        return guarded(key, fn, exact=True, threaded=threaded, coded=CODED,
                       log_refusals=True)

    def _on_state(self, query: zenoh.Query) -> None:
        query.reply(f"{self.prefix}/robot_state", wire.encode(self.state().to_dict()),
                    encoding=wire.JSON)

    def state(self) -> JointState:
        """The robot's state. A twin not opened yet is where it will start: said without
        opening it (seconds on CAD meshes: longer than a scene attach waits for it)."""
        if self.spec.kind == "sim" and self._executor is None:
            return twin_start(self.description)
        return self.robot().state()

    def _on_change(self, sample: zenoh.Sample) -> None:
        """A kept-scene change (Zenoh's thread: handed to the running execution's
        reactor, which checks on its own thread)."""
        react = self.reactor
        if react is None:
            return
        try:
            msg = orjson.loads(sample.payload.to_bytes())
        except orjson.JSONDecodeError as e:
            _log.warning("a scene change that is not JSON was ignored: %s", e)
            return
        if isinstance(msg, dict) and isinstance(msg.get("revision"), int):
            react.changed(msg)

    def scene_revision(self) -> int | None:
        """The kept scene's revision now (None: no kept scene)."""
        snap = self.scene_source() if self.scene_source is not None else None
        return snap.revision if snap is not None else None

    def _on_cancel(self, query: zenoh.Query) -> None:
        raw = payload_of(query)
        body = wire.parse_json(raw) if raw else {}
        want = body.get("execution") if isinstance(body, dict) else None
        cur = self._current
        hit = cur is not None and (want is None or want == cur)
        if hit:
            _log.info("execution %s: cancel requested", cur)
            self.cancel.set()
        query.reply(f"{self.prefix}/execute/cancel",
                    wire.encode({"cancelled": cur if hit else None}), encoding=wire.JSON)

    def _on_execute(self, query: zenoh.Query) -> None:
        req = ExecuteRequest.decode(payload_of(query))
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
            self.cancel.clear()
            run = Run(self, query, execution, req)
            plan_req = req.plan or {}
            self.scene_to_twin(robot, plan_req.get("obstacles") or (), req.twin,
                                ground=bool(plan_req.get("ground", True)))
            if req.trajectory is not None:
                # a plan reply says the scene it was planned in; else the scene now
                rev = req.trajectory.get("scene_revision")
                run.revision = rev if isinstance(rev, int) else self.scene_revision()
                run.start_with(SampledTrajectory.from_json(req.trajectory))
                return
            plan = dict(req.plan or {})
            if "start" not in plan:
                plan["start"] = plan_start(robot, self.description)
            self.plan(plan, run.on_planned)
        except BaseException:
            self.finish()
            raise

    def scene_to_twin(self, robot: Robot, own: Sequence[Mapping[str, Any]],
                       twin: Mapping[str, Any] | None = None, *, ground: bool = True,
                       keep_loose: bool = False) -> None:
        """Give a twin the kept scene now with the plan's ``own`` obstacles and its
        ``ground``, or a task's ``twin`` objects (:meth:`TwinScene.give`)."""
        snap = self.scene_source() if self.scene_source is not None else None
        self.twin_scene.give(robot, snap, own, twin, ground=ground, keep_loose=keep_loose)

    def plan(self, request: Mapping[str, Any], respond: Callable[[Outcome], None]) -> None:
        """Hand the plan ``request`` to the pool (checked first); ``respond`` gets its outcome."""
        if self.submit_plan is None:
            raise InvalidRequest("this service cannot plan", field="plan")
        self.submit_plan(wire.decode("plan", wire.encode(request)), respond)

    def _blend(self, query: zenoh.Query, req: ExecuteRequest) -> None:
        """A new goal for the moving arm: plan from the setpoint ``req.blend_lead`` ahead
        (a moving start) and switch to it at that tick, where a twin also takes the
        world the plan was made in (:meth:`TwinScene.at_switch`); one reply, ``blended``
        or an error (``TOO_LATE`` when the arm stops first or planning took too long)."""
        if req.plan is None:
            raise InvalidRequest("a blend needs a plan request (the new goal)", field="plan")
        ex, execution = self.running, self._current
        if ex is None:
            raise TooLate("nothing is moving: send the goal without blend")
        k, q, qd, qdd = ex.lookahead(req.blend_lead)
        names = ex.robot.joint_names
        # the world the blend is planned in, for the twin at the switch tick
        snap = self.scene_source() if self.scene_source is not None else None
        own = req.plan.get("obstacles") or ()
        ground = bool(req.plan.get("ground", True))  # the twin's floor, as the plan's
        plan = {**req.plan, "start": dict(zip(names, q.tolist())),
                "start_velocity": dict(zip(names, qd.tolist())),
                "start_acceleration": dict(zip(names, qdd.tolist()))}
        key = f"{self.prefix}/execute"

        def on_planned(outcome: Outcome) -> None:
            with answering(query, key, internal="the blend failed", coded=CODED,
                           log_refusals=True):
                if isinstance(outcome, Failure):
                    reply_failure(query, outcome)
                else:
                    traj = SampledTrajectory.from_json(orjson.loads(outcome.body))
                    ex.switch(traj, k, on_switch=self.twin_scene.at_switch(
                        ex.robot, snap, own, ground=ground))
                    query.reply(key, wire.encode({"event": "blended", "execution": execution,
                                                  "tick": k, "duration": traj.duration}),
                                encoding=wire.JSON)
            query.drop()
        self.plan(plan, on_planned)

    def finish(self) -> None:
        """The execution is over: the robot takes the next one."""
        self._current = None
        if self._busy.locked():
            self._busy.release()


def execute_extension(spec: RobotSpec, *, tick_sink: OpenTickSink | None = None
                      ) -> Callable[[Host], ExecuteService]:
    """An extension (:mod:`arduinobot.service.extension`) serving ``<prefix>/execute`` on
    the robot ``spec`` describes (started once the service's session is open), its plans
    through the host's pool, a twin taking the host's kept scene;
    ``tick_sink(session, description)`` opens another consumer of every tick (``serve
    --ros2``'s /joint_states), closed with the service."""
    def make(host: Host) -> ExecuteService:
        sink = tick_sink(host.session, host.description) if tick_sink is not None else None
        svc = ExecuteService(host.session, host.prefix, host.description, spec,
                             submit_plan=host.submit_plan, submit=host.submit, tick_sink=sink,
                             scene_source=host.scene)
        try:
            svc.start()
        except BaseException:
            svc.close()
            raise
        return svc
    return make
