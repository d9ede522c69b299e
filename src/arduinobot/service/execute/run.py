"""One execution on the service's robot: its thread, and its replies on the execute
query (``started``, ``progress`` every :data:`PROGRESS_EVERY` ticks, ``finished`` with the
report, or the coded error that ended it), until the final report. While it moves, its
:class:`~arduinobot.service.execute.react.Reactor` re-checks the rest on every scene
change (events ``changed``, ``stopped``, ``replanned``); a replanned execution plays in
legs (a task's: its remaining steps planned again), the report is the last one's with
every leg's summary (``legs``)."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any, Protocol

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.execution.executor import Executor, plan_start
from arduinobot.execution.report import ExecutionReport, Tick
from arduinobot.execution.robots.base import PortError, Robot, RobotError
from arduinobot.execution.segments import SampledTrajectory, check_fits
from arduinobot.service.execute.io import CODED, ExecuteRequest
from arduinobot.service.execute.react import Reactor, Verdict
from arduinobot.service.execute.task_react import TaskPieces
from arduinobot.service.execute.task_replan import resume_job, resumed
from arduinobot.service.messages import Failure, Outcome, Submit, outcome_of
from arduinobot.service.queries import answering, reply_error

_log = logging.getLogger(__name__)

PROGRESS_EVERY = 10  # ticks between progress replies (10 Hz at 100 Hz)
MAX_LEGS = 10  # an execution replans at most this often less one (a scene that keeps
# moving into the path would otherwise keep the arm stopping forever)


class RunHost(Protocol):
    """What a run needs of the service that runs it (:class:`arduinobot.service.execute.execution.ExecuteService`)."""

    session: zenoh.Session
    prefix: str
    description: Description
    cancel: threading.Event  # set: the running execution stops smoothly
    running: Executor | None  # the executor playing now (a blend switches it)
    thread: threading.Thread | None  # the running execution's (joined on close)

    def executor(self) -> Executor:
        """The robot's executor (the robot opened if need be)."""
        ...

    def drop_robot(self) -> None:
        """Release the robot (its port failed: the next request opens it again)."""
        ...

    def publish_tick(self, tick: Tick) -> dict[str, Any]:
        """Publish ``tick`` (joint_states and any other consumer); its message."""
        ...

    def finish(self) -> None:
        """The execution is over: the robot takes the next one."""
        ...

    submit: Submit | None  # a job through the pool (the rechecks), None: no pool
    reactor: Reactor | None  # the running execution's, hearing the scene's changes

    def scene_revision(self) -> int | None:
        """The kept scene's revision now (None: no kept scene)."""
        ...

    def scene_to_twin(self, robot: Robot, own: Sequence[Mapping[str, Any]],
                      twin: Mapping[str, Any] | None = None, *, ground: bool = True,
                      keep_loose: bool = False) -> None:
        """Give a twin the kept scene now with a plan's own obstacles, or a task's
        ``twin`` objects (``keep_loose``: those it has stay as simulated)."""
        ...

    def plan(self, request: Mapping[str, Any], respond: Callable[[Outcome], None]) -> None:
        """A plan request through the pool; ``respond`` gets its outcome."""
        ...


class Run:
    """One execution: its query (replied to until the final report), its thread."""

    def __init__(self, svc: RunHost, query: zenoh.Query, execution: str,
                 req: ExecuteRequest) -> None:
        self.svc, self.query, self.execution, self.req = svc, query, execution, req
        self.key = f"{svc.prefix}/execute"
        #: the kept scene's revision the trajectory was planned in (a plan reply's)
        self.revision: int | None = None
        self.stopped_why: str | None = None  # why a stop for a change ended it
        self.stopped_in: dict[str, Any] | None = None  # a task's step it stopped in
        # a task's steps along the trajectory: its rest is re-checked step by step
        self.task = TaskPieces.of(req.task) if req.task is not None else None
        self._grip: Callable[[Tick], None] | None = None  # a twin's task grasps

    def on_planned(self, outcome: Outcome) -> None:
        if isinstance(outcome, Failure):
            self._fail(outcome.code, outcome.message, outcome.details)
            return
        try:
            body = orjson.loads(outcome.body)
            self.revision = body.get("scene_revision")
            self.start_with(SampledTrajectory.from_json(body))
        except RobotError as e:
            self._fail(e.code, e.message, e.details)
        except Exception as e:  # noqa: BLE001 -- answered, never swallowed silently
            _log.exception("execution %s: could not start", self.execution)
            self._fail(Code.INTERNAL, str(e), {})

    def start_with(self, traj: SampledTrajectory) -> None:
        t = threading.Thread(target=self._run, args=(traj,), name=f"execute-{self.execution}",
                             daemon=True)
        self.svc.thread = t
        t.start()

    def _fail(self, code: str, message: str, details: Mapping[str, Any]) -> None:
        reply_error(self.query, code, message, details)
        self.query.drop()
        self.svc.finish()

    def _reply(self, body: Mapping[str, Any]) -> None:
        self.query.reply(self.key, wire.encode(body), encoding=wire.JSON)

    def _executor(self) -> Executor:
        """An executor for this run: the robot's, with the request's start options, that
        publishes joint_states and replies progress."""
        base = self.svc.executor()

        self._grip = self._grasps(base.robot, self.req.twin)

        def on_tick(tick: Tick) -> None:
            if self._grip is not None:
                self._grip(tick)
            msg = self.svc.publish_tick(tick)
            if tick.index % PROGRESS_EVERY == 0:
                self._reply({"event": "progress", "execution": self.execution,
                             "time": tick.time, **msg})
        return Executor(base.robot, base.limits, torques=base.torques, on_tick=on_tick,
                        options=replace(base.options,
                                        start_tolerance=self.req.start_tolerance,
                                        move_to_start=self.req.move_to_start))

    @staticmethod
    def _grasps(robot: Robot, twin: Mapping[str, Any] | None
                ) -> Callable[[Tick], None] | None:
        """A twin's grip schedule for a task's trajectory (a real arm has no weld)."""
        grasps = (twin or {}).get("grasps") or ()
        if not grasps:
            return None
        from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
        from arduinobot.execution.robots.twin_tasks import grasp_schedule
        if not isinstance(robot, SimArduinobot):
            return None
        return grasp_schedule(robot, [(float(g["time"]), g["object"], g["hold"])
                                      for g in grasps])

    def _run(self, traj: SampledTrajectory) -> None:
        svc = self.svc
        watch = None
        done: dict[str, Any] | None = None
        react: Reactor | None = None
        with answering(self.query, f"execution {self.execution}",
                       internal="the execution failed", coded=CODED, log_refusals=True):
            try:
                if self.req.client is not None:
                    watch = self._watch_client(self.req.client)
                ex = self._executor()
                check_fits(traj, svc.description)  # a plan for another robot: refused
                ex.check_start(traj)  # refuse before telling the client it started
                svc.running = ex
                self._reply({"event": "started", "execution": self.execution,
                             "duration": traj.duration, "joint_names": list(traj.joint_names)})
                react = self._reactor(ex)
                t0 = time.monotonic()
                report, legs = self._legs(ex, traj, react)
                if watch is not None:  # done: the client may leave now
                    watch.undeclare()
                    watch = None
                _log.info("execution %s %s after %.3f s", self.execution, report.outcome,
                          time.monotonic() - t0)
                done = {"event": "finished", "execution": self.execution,
                        "report": {**report.to_dict(),
                                   **({"legs": legs} if len(legs) > 1 else {})}}
                if self.stopped_why is not None:
                    done["report"]["stopped_because"] = self.stopped_why
                if self.stopped_in is not None:  # a task's step
                    done["report"]["stopped_in"] = self.stopped_in
                objects = (self.req.twin or {}).get("objects") or ()
                if objects and hasattr(ex.robot, "object_pose"):
                    # where the twin's objects ended: MuJoCo's state, not the plan's
                    done["objects"] = {o["object"]["id"]: ex.robot.object_pose(
                        o["object"]["id"])[:3, 3].tolist() for o in objects}
            finally:
                svc.running = None
                if react is not None:
                    svc.reactor = None
                    react.close()
                if watch is not None:
                    watch.undeclare()
                svc.finish()
            # said once the robot is free: a client that sends its next motion as soon as
            # it hears this one finished must not be told BUSY
            if done is not None:
                self._reply(done)
        self.query.drop()

    def _reactor(self, ex: Executor) -> Reactor | None:
        """The execution's reaction to scene changes (:mod:`.react`), heard from now on;
        None when the service has no pool to check with."""
        svc = self.svc
        if svc.submit is None:
            return None
        # a task's joined motion carries objects that change along it (attach, detach):
        # its rest is checked step by step, each in its own world (.task_react)
        react = Reactor(ex, svc.submit, self.req.plan or {}, on_change=self.req.on_change,
                        emit=lambda body: self._reply({"event": body["event"],
                                                       "execution": self.execution, **body}),
                        scene_revision=svc.scene_revision, task=self.task)
        svc.reactor = react
        return react

    def _legs(self, ex: Executor, traj: SampledTrajectory, react: Reactor | None
              ) -> tuple[ExecutionReport, list[dict[str, Any]]]:
        """Play ``traj``; after a stop for a scene change, with ``replan``, plan from the
        stopped state to the same goal and play that, up to :data:`MAX_LEGS` legs. The
        last leg's report, and every leg's summary."""
        svc = self.svc
        legs: list[dict[str, Any]] = []
        revision = self.revision if self.revision is not None else (svc.scene_revision() or 0)
        while True:
            halt = threading.Event()
            if react is not None:
                react.begin(halt, traj, revision)
            try:
                report = ex.execute(traj, cancel=svc.cancel, halt=halt)
            except PortError:
                svc.drop_robot()  # unplugged or stalled: the next request reopens it
                raise
            finally:
                if react is not None:
                    react.end()
            legs.append(report.to_dict())
            if report.outcome != "stopped" or react is None or react.verdict is None:
                return report, legs
            self._said_stop(ex, report, react.verdict)
            if self.req.on_change != "replan" or len(legs) >= MAX_LEGS:
                self.stopped_why = ("on_change is stop" if self.req.on_change == "stop"
                                    else f"{MAX_LEGS} legs replanned already")
                return report, legs
            got = self._replan(ex, traj) if self.task is None else \
                self._replan_task(ex, react, rest_at=ex.last_stop_end
                                  if ex.last_stop_end is not None else report.cancelled_at)
            if got is None:
                return report, legs
            traj, revision = got
            self.stopped_in = None  # it goes on: a later stop names its own step

    def _said_stop(self, ex: Executor, report: ExecutionReport, verdict: Verdict) -> None:
        """The ``stopped`` event: where and how fast the arm stopped for the change."""
        ch = verdict.change
        rest = ex.last_stop_end
        until = verdict.certified_until
        # the leg's tick that sent the first stop setpoint
        tick = report.phases.index("stop") if "stop" in report.phases else None
        at = rest if rest is not None else report.cancelled_at
        if self.task is not None and at is not None:
            self.stopped_in = self.task.at(at)  # the step it came to rest in
        self._reply({"event": "stopped", "execution": self.execution,
                     **({"step": self.stopped_in} if self.stopped_in is not None else {}),
                     **({"refused_step": dict(verdict.step)} if verdict.step else {}),
                     "revision": ch.revision, "tick": tick,
                     "trajectory_time": report.cancelled_at, "stop_time": report.stop_time,
                     "stop_kind": ex.last_stop, "rest_at": rest,
                     "certified_until": until,
                     "before": rest is not None and until is not None
                     and rest <= until + 1e-9,
                     "stop_ms": None if ex.stop_sent is None
                     else 1e3 * (ex.stop_sent - ch.arrived)})

    def _replan(self, ex: Executor, traj: SampledTrajectory
                ) -> tuple[SampledTrajectory, int] | None:
        """The same goal from the stopped state, planned in the scene now (the twin
        takes it first); None (``stopped_why`` set, said on the stream) when no plan."""
        svc = self.svc
        if self.req.plan is not None:
            plan = {k: v for k, v in self.req.plan.items()
                    if k not in ("start", "start_velocity", "start_acceleration")}
        else:  # a trajectory: its last state is the goal
            end = traj.positions[-1]
            plan = {"goal": {"joints": dict(zip(traj.joint_names, map(float, end)))}}
        plan["start"] = plan_start(ex.robot, svc.description)
        own = plan.get("obstacles") or ()
        svc.scene_to_twin(ex.robot, own, None, ground=bool(plan.get("ground", True)))
        box: list[Outcome] = []
        got = threading.Event()

        def respond(outcome: Outcome) -> None:
            box.append(outcome)
            got.set()
        svc.plan(plan, respond)
        got.wait()
        outcome = box[0]
        if isinstance(outcome, Failure):
            self.stopped_why = f"replanning failed: {outcome.code}: {outcome.message}"
            self._reply({"event": "replanned", "execution": self.execution, "ok": False,
                         "error": outcome.to_json()["error"]})
            return None
        body = orjson.loads(outcome.body)
        new = SampledTrajectory.from_json(body)
        revision = int(body.get("scene_revision", 0))
        self._reply({"event": "replanned", "execution": self.execution, "ok": True,
                     "duration": new.duration, "revision": revision})
        return new, revision

    def _replan_task(self, ex: Executor, react: Reactor, *, rest_at: float | None
                     ) -> tuple[SampledTrajectory, int] | None:
        """The task's remaining steps planned from the stopped state (:mod:`.task_replan`),
        in the scene now; None (``stopped_why`` set, said on the stream) when not."""
        svc = self.svc
        assert self.task is not None and svc.submit is not None
        job, why = (None, "it did not stop on its path") if rest_at is None else \
            resume_job(self.task, rest_at, plan_start(ex.robot, svc.description),
                       on_change=self.req.on_change)
        outcome = None if job is None else outcome_of(svc.submit, "task", job)
        if outcome is None or isinstance(outcome, Failure):
            error = {"message": why} if outcome is None else outcome.to_json()["error"]
            self.stopped_why = f"replanning the task's rest failed: {error['message']}"
            self._reply({"event": "replanned", "execution": self.execution, "ok": False,
                         "error": error, **({"step": self.stopped_in}
                                            if self.stopped_in else {})})
            return None
        assert outcome.execute is not None
        planned, body = orjson.loads(outcome.body), orjson.loads(outcome.execute)
        new = SampledTrajectory.from_json(body["trajectory"])
        self.task = react.task = TaskPieces.of(body["task"])
        if body.get("twin") is not None:
            # the world the rest was planned in (the kept scene now, a sphere added on
            # the carried box's way), the task's objects as the twin has them
            svc.scene_to_twin(ex.robot, (), body["twin"], keep_loose=True)
        self._grip = self._grasps(ex.robot, body.get("twin"))
        revision = int(planned.get("scene_revision", 0))
        self._reply({"event": "replanned", "execution": self.execution, "ok": True,
                     "duration": new.duration, "revision": revision,
                     "from_step": resumed(job),
                     "steps": len(planned["steps"]),
                     "planning_time": planned.get("planning_time")})
        return new, revision

    def _watch_client(self, client: str) -> zenoh.Subscriber:
        """Cancel when the client's liveliness token goes (the client died or lost the
        network); refuse if it is not there to begin with."""
        key = f"{self.svc.prefix}/execute/client/{client}"
        if not any(r.ok is not None for r in self.svc.session.liveliness().get(key,
                                                                               timeout=2.0)):
            raise InvalidRequest(f"no liveliness token {key}: declare it before executing",
                                 field="client")
        cancel, execution = self.svc.cancel, self.execution

        def on_change(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.DELETE:
                _log.warning("execution %s: client %s lost, stopping", execution, key)
                cancel.set()
        return self.svc.session.liveliness().declare_subscriber(key, on_change)
