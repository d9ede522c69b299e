"""One execution on the service's robot: its thread, and its replies on the execute
query (``started``, ``progress`` every :data:`PROGRESS_EVERY` ticks, ``finished`` with the
report, or the coded error that ended it), until the final report."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Mapping
from dataclasses import replace
from typing import Any, Protocol

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.execution.executor import Executor
from arduinobot.execution.report import Tick
from arduinobot.execution.robots.base import PortError, RobotError
from arduinobot.execution.segments import SampledTrajectory, check_fits
from arduinobot.service.execute.io import CODED, ExecuteRequest
from arduinobot.service.messages import Failure, Outcome
from arduinobot.service.queries import answering, reply_error

_log = logging.getLogger(__name__)

PROGRESS_EVERY = 10  # ticks between progress replies (10 Hz at 100 Hz)


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


class Run:
    """One execution: its query (replied to until the final report), its thread."""

    def __init__(self, svc: RunHost, query: zenoh.Query, execution: str,
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

        grasps = (self.req.twin or {}).get("grasps") or ()
        grip = None
        if grasps:  # a twin grips a task's objects (a real arm has no weld to switch)
            from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
            from arduinobot.execution.robots.twin_tasks import grasp_schedule
            if isinstance(base.robot, SimArduinobot):
                grip = grasp_schedule(base.robot, [(float(g["time"]), g["object"], g["hold"])
                                                   for g in grasps])

        def on_tick(tick: Tick) -> None:
            if grip is not None:
                grip(tick)
            msg = self.svc.publish_tick(tick)
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
        done: dict[str, Any] | None = None
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
                t0 = time.monotonic()
                try:
                    report = ex.execute(traj, cancel=svc.cancel)
                except PortError:
                    svc.drop_robot()  # unplugged or stalled: the next request reopens it
                    raise
                if watch is not None:  # done: the client may leave now
                    watch.undeclare()
                    watch = None
                _log.info("execution %s %s after %.3f s", self.execution, report.outcome,
                          time.monotonic() - t0)
                done = {"event": "finished", "execution": self.execution,
                        "report": report.to_dict()}
                objects = (self.req.twin or {}).get("objects") or ()
                if objects and hasattr(ex.robot, "object_pose"):
                    # where the twin's objects ended: MuJoCo's state, not the plan's
                    done["objects"] = {o["object"]["id"]: ex.robot.object_pose(
                        o["object"]["id"])[:3, 3].tolist() for o in objects}
            finally:
                svc.running = None
                if watch is not None:
                    watch.undeclare()
                svc.finish()
            # said once the robot is free: a client that sends its next motion as soon as
            # it hears this one finished must not be told BUSY
            if done is not None:
                self._reply(done)
        self.query.drop()

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
