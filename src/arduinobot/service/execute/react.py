"""Reacting while the arm moves: every kept-scene change re-checks the rest of the motion.

The execute wing follows ``<prefix>/scene/changes`` (:mod:`arduinobot.service.scene.sync`:
an apply, a new cloud, an object seen all make one). While an execution plays, each
change it hears goes to that execution's :class:`Reactor` (the Zenoh callback only
queues it). The reactor's own thread takes the newest change, samples the trajectory
playing now at every control tick from the current one to its end (the setpoints the
arm is still to be sent) and has a worker certify them against the scene as it is now
(a ``recheck`` job, :mod:`arduinobot.service.plan.recheck`: the planner's proof, in the
world a plan would have now). Certified: the motion goes on. Not certified: by the
request's ``on_change``,

- ``ignore``: it goes on, and the stream says so;
- ``stop`` and ``replan``: it sets the execution's ``halt``; at its next tick the
  executor brakes along the path within every limit
  (:func:`arduinobot.execution.stops.choose_stop`). The braking stays on the path, so
  it passes only through states the recheck certified when it comes to rest at or
  before the last state of the certified prefix (``certified_until``); the run
  (:mod:`.run`) says whether it did (``before``), and with ``replan`` plans from the
  stopped state to the same goal, in the new scene, and goes on.

A task's rest is cut by its steps (:mod:`.task_react`): each step's piece is checked in
the world that step was planned in (what the task carries there, the pairs allowed
there) with the kept scene now, and the events name the steps; with ``replan`` the run
plans the task's remaining steps from the stopped state (:mod:`.task_replan`).

Every change handled is one ``changed`` event on the execution's stream: the revision,
the objects added, removed, attached and detached, whether the rest was certified, the
action, and how long the recheck took; a stop adds ``stopped`` (the tick, the time from
the apply's arrival to the first stop setpoint [ms], where it came to rest). A check
that fails (a worker's error, a scene catching up) counts as not certified: the arm
stops rather than guesses.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import orjson

from arduinobot.contract.outcomes import OnChange
from arduinobot.execution.executor import Executor
from arduinobot.execution.segments import Segment
from arduinobot.service.execute.task_react import TaskPieces
from arduinobot.service.messages import Failure, Submit, outcome_of

_log = logging.getLogger(__name__)

#: what a change message names (``<prefix>/scene/changes``)
CHANGE_LISTS = ("added", "removed", "attached", "detached")


@dataclass(frozen=True)
class Change:
    """One or more kept-scene changes heard together: the newest revision, every id
    they name, and when the first of them arrived (wall clock [s])."""

    revision: int
    arrived: float
    ids: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    cleared: bool = False
    heard: float = 0.0  # when this service heard of it (wall clock [s])

    @classmethod
    def of(cls, msg: Mapping[str, Any], heard: float) -> Change:
        arrived = msg.get("arrived")
        return cls(int(msg.get("revision", 0)),
                   float(arrived) if isinstance(arrived, (int, float)) else heard,
                   {k: tuple(str(i) for i in msg.get(k) or ()) for k in CHANGE_LISTS},
                   bool(msg.get("cleared")), heard)

    def merge(self, later: Change) -> Change:
        return Change(max(self.revision, later.revision), min(self.arrived, later.arrived),
                      {k: (*self.ids.get(k, ()), *later.ids.get(k, ())) for k in CHANGE_LISTS},
                      self.cleared or later.cleared, min(self.heard, later.heard))

    def to_json(self) -> dict[str, Any]:
        """The change as the ``changed`` event says it; ``heard_ms``: from the apply's
        arrival to this service hearing of it (the apply, its file, its replication)."""
        return {"revision": self.revision, **{k: list(v) for k, v in self.ids.items()},
                "cleared": self.cleared,
                "heard_ms": 1e3 * (self.heard - self.arrived) if self.heard else None}


@dataclass(frozen=True)
class Verdict:
    """What a recheck decided for a running leg (kept for the leg's ``stopped`` event)."""

    change: Change
    certified: bool
    action: str  # continued | ignored | stop
    #: trajectory time [s] of the last certified state (None: certified, or none was)
    certified_until: float | None = None
    refused: Mapping[str, Any] | None = None  # {"time": [s], "pair": [a, b]}
    seconds: float = 0.0  # the recheck's, in the worker
    #: a task's: the step the refusal fell in (:meth:`.task_react.TaskPieces.step`)
    step: Mapping[str, Any] | None = None


class Reactor:
    """One execution's reaction to scene changes (see the module doc).

    Args:
        ex: the executor playing the execution.
        submit: the service's job submission (the recheck goes to a worker).
        plan: the plan request the motion was planned from (its own ``obstacles``,
            ``ground`` and ``attached`` are part of the world it is checked in).
        on_change: ``replan``, ``stop`` or ``ignore``.
        emit: sends one event body on the execution's stream.
        scene_revision: the kept scene's revision now (None: no kept scene).
        task: a task's steps (:mod:`.task_react`): its rest is checked piece by piece,
            each step's in its own world, and the events name the steps.
    """

    def __init__(self, ex: Executor, submit: Submit, plan: Mapping[str, Any], *,
                 on_change: OnChange, emit: Callable[[dict[str, Any]], None],
                 scene_revision: Callable[[], int | None],
                 task: TaskPieces | None = None) -> None:
        self.ex, self.submit, self.plan = ex, submit, plan
        self.task = task  # a replan's new leg puts its own
        self.on_change, self.emit, self.scene_revision = on_change, emit, scene_revision
        self._changes: queue.Queue[Change | None] = queue.Queue()
        self._lock = threading.Lock()
        # the leg playing: its halt event, its trajectory and the revision it is
        # certified against (None between legs)
        self._leg: tuple[threading.Event, Segment, int] | None = None
        self.verdict: Verdict | None = None  # the leg's stop, when one was asked
        self._thread = threading.Thread(target=self._loop, name="execute-react", daemon=True)
        self._thread.start()

    # -- from the service -------------------------------------------------------------------
    def changed(self, msg: Mapping[str, Any]) -> None:
        """A change heard (on Zenoh's callback thread: queued, nothing more)."""
        self._changes.put(Change.of(msg, time.time()))

    def begin(self, halt: threading.Event, trajectory: Segment, revision: int) -> None:
        """A leg starts, certified against scene ``revision``: changes count from there
        (one the leg's plan did not see is checked at once)."""
        with self._lock:
            self._leg, self.verdict = (halt, trajectory, revision), None
        now = self.scene_revision()
        if now is not None and now > revision:
            t = time.time()
            self._changes.put(Change(now, t, heard=t))

    def end(self) -> None:
        """The leg is over (played, stopped or failed)."""
        with self._lock:
            self._leg = None

    def close(self) -> None:
        self.end()
        self._changes.put(None)
        self._thread.join(30.0)

    # -- the reactor's thread -----------------------------------------------------------------
    def _loop(self) -> None:
        while (change := self._changes.get()) is not None:
            try:  # the newest of what arrived meanwhile, every id named
                while (later := self._changes.get_nowait()) is not None:
                    change = change.merge(later)
                else:
                    self._changes.put(None)  # closing: after this one
            except queue.Empty:
                pass
            try:
                self._react(change)
            except Exception as e:  # noqa: BLE001 -- logged, said, and a stop asked
                _log.exception("reacting to scene revision %d failed", change.revision)
                self._stop_on_error(change, e)

    def _rest(self, seg: Segment, t: float) -> tuple[dict[str, Any], np.ndarray]:
        """A single motion's recheck data from trajectory time ``t`` [s] on: every
        control tick's state, in the plan request's world; and the ticks' times [s]."""
        dt = 1.0 / self.ex.options.rate
        ts = np.append(np.arange(t, seg.duration, dt), seg.duration)
        qs = np.array([seg.evaluate(float(x))[0] for x in ts])
        plan = self.plan
        data: dict[str, Any] = {"joint_names": list(seg.joint_names),
                                "positions": qs.tolist(),
                                "obstacles": list(plan.get("obstacles") or ()),
                                "ground": bool(plan.get("ground", True))}
        if plan.get("attached"):
            data["attached"] = list(plan["attached"])
        return data, ts

    def _stop_on_error(self, change: Change, error: Exception) -> None:
        """Not checked (the pool refused the job, a scene catching up, a bug): as not
        certified, the arm stops (unless told to ignore), and the stream says why."""
        with self._lock:
            leg = self._leg
        if leg is None:
            return
        action = "ignored" if self.on_change == "ignore" else "stop"
        code = getattr(error, "code", "INTERNAL")  # a coded error's, else a bug's
        if action == "stop":
            self.verdict = Verdict(change, False, "stop")
            leg[0].set()
        self.emit({"event": "changed", **change.to_json(), "certified": False,
                   "action": action, "refused": {"error": {
                       "code": str(getattr(code, "value", code)),
                       "message": str(getattr(error, "message", error))}}})

    def _react(self, change: Change) -> None:
        with self._lock:
            leg = self._leg
        if leg is None or change.revision <= leg[2]:
            return  # between legs (a replan plans in the newest scene), or already seen
        halt, traj, _ = leg
        if self.task is not None and self.task.unchecked is not None:
            with self._lock:
                if self._leg is leg:
                    self._leg = (halt, traj, change.revision)
            self.emit({"event": "changed", **change.to_json(), "certified": None,
                       "action": "not_checked", "reason": self.task.unchecked})
            return
        playing = self.ex.playing()
        if playing is None or halt.is_set():
            return
        phase, seg, t = playing
        if phase != "trajectory":
            seg, t = traj, 0.0  # still moving to the start: the whole trajectory
        elif phase == "trajectory" and t >= seg.duration:
            return  # its last setpoint is out: nothing left to check
        spans: list[tuple[int, np.ndarray]] = []
        if self.task is not None:  # each step's piece in its own world
            data, spans = self.task.rest(seg, t, self.ex.options.rate)
            if not spans:
                return  # only an attach or a detach is left
            ts = np.concatenate([s[1] for s in spans])
        else:
            data, ts = self._rest(seg, t)
        out = outcome_of(self.submit, "recheck", data)
        with self._lock:
            ended = self._leg is not leg
            if not ended:
                self._leg = (halt, traj, change.revision)
        if ended:  # the leg ended (or was stopped) while it was checked: said, not acted on
            _log.warning("scene revision %d: the motion ended before its recheck did",
                         change.revision)
            self.emit({"event": "changed", **change.to_json(), "certified": None,
                       "action": "ended_first"})
            return
        if isinstance(out, Failure):
            _log.error("scene revision %d: the recheck failed (%s: %s): stopping",
                       change.revision, out.code, out.message)
            verdict = Verdict(change, False, "ignored" if self.on_change == "ignore"
                              else "stop", refused={"error": out.to_json()["error"]})
        else:
            body = orjson.loads(out.body)
            seconds = float(body.get("seconds", 0.0))
            if body["certified"]:
                verdict = Verdict(change, True, "continued", seconds=seconds)
            elif self.task is not None:
                until, refused, step = self.task.where(body, spans)
                verdict = Verdict(change, False, "ignored" if self.on_change == "ignore"
                                  else "stop", certified_until=until, refused=refused,
                                  seconds=seconds, step=step)
            else:
                safe = int(body["safe"])
                ref = body["refused"]
                verdict = Verdict(
                    change, False, "ignored" if self.on_change == "ignore" else "stop",
                    certified_until=float(ts[safe]) if safe >= 0 else None,
                    refused={"time": float(ts[min(int(ref["state"]), len(ts) - 1)]),
                             "pair": ref["pair"]}, seconds=seconds)
        if verdict.action == "stop":
            self.verdict = verdict
            halt.set()  # the executor brakes at its next tick
        decided = time.time()
        self.emit({"event": "changed", **change.to_json(), "certified": verdict.certified,
                   "action": verdict.action, "recheck_ms": 1e3 * verdict.seconds,
                   # from the apply's arrival to the decision (the halt set)
                   "decided_ms": 1e3 * (decided - change.arrived),
                   **({"refused": verdict.refused} if verdict.refused else {}),
                   **({"certified_until": verdict.certified_until}
                      if verdict.certified_until is not None else {}),
                   # a task's: the step playing when the check began, the refused one's
                   **({"running": self.task.at(t if phase == "trajectory" else 0.0)}
                      if self.task is not None else {}),
                   **({"step": dict(verdict.step)} if verdict.step is not None else {})})
        _log.info("scene revision %d while moving: %s (%s)", change.revision,
                  "certified" if verdict.certified else "not certified", verdict.action)
