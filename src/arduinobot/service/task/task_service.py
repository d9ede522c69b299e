"""``<prefix>/task``: plan a task as a whole and optionally run it on the service's robot.

A request (``src/arduinobot/contract/schema/task_request.json``) names a task of the service's
``tasks.yaml`` (``name`` or ``number``) or gives one (``task``). The service plans every
step in order (:func:`arduinobot.planner.tasks.plan_task`, a ``task`` job of the worker pool, as
plans are: the serving process never imports the planner, and tasks plan in parallel
with each other and with plans) before anything moves and replies
``{"event": "planned", ...}`` (each step's start time,
duration, start and end states, what the robot carried, its plan reply); a step that
fails answers its own error code with ``details.step`` and ``details.error``. With
``"execute": true`` the whole task, joined into one trajectory, then goes to the
service's own ``<prefix>/execute``, whose stream (``started``, ``progress``,
``finished``) is relayed on the same query: ``<prefix>/execute/cancel`` stops it
smoothly mid-step, like any execution. A task without ``start`` starts, when executed,
from the robot's state (``<prefix>/robot_state``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.outcomes import DEFAULT_ON_CHANGE
from arduinobot.contract.packed import pack
from arduinobot.description import Description
from arduinobot.description.moveit_config import NamedTask, find_task, read_tasks
from arduinobot.scene.obstacles import AttachedObject, Obstacle, refuse_files
from arduinobot.scene.state import SceneSnapshot, with_scene
from arduinobot.service.extension import Host
from arduinobot.service.messages import Failure, Outcome, Submit, Success, outcome_of
from arduinobot.service.queries import guarded, reply_error, reply_failure

if TYPE_CHECKING:  # the planner (OMPL) loads in the workers, never with `serve`
    from arduinobot.planner.tasks import Task, TaskResult

_log = logging.getLogger(__name__)

#: how long the relayed execute stream may last [s] (progress arrives every 0.1 s)
STREAM_LIMIT = 24 * 3600.0


def planned_body(result: TaskResult, *, name: str | None, trajectories: bool = True
                 ) -> dict[str, Any]:
    """The ``planned`` reply of a task (see ``task_response.json``)."""
    from arduinobot.service.plan.plan_io import plan_response
    steps = []
    for s, t0 in zip(result.steps, result.boundaries()):
        item: dict[str, Any] = {
            "index": s.index, "kind": s.kind, "label": s.label, "group": s.group,
            "start_time": t0, "duration": s.duration, "start": dict(s.start),
            "end": dict(s.end), "carried": list(s.carried)}
        if s.object is not None:
            item["object"], item["link"] = s.object, s.link
        if s.part_of is not None:
            item["part_of"] = s.part_of
        if s.result is not None:
            item["certified"] = bool(s.result.verification.certified)
            item["verified"] = bool(s.result.verification.ok)
            if trajectories:
                item["plan"] = plan_response(s.result)
        steps.append(item)
    return {"event": "planned", "name": name, "duration": result.duration,
            "planning_time": result.planning_time, "joint_names": list(result.joint_names),
            "obstacles": [obstacle_json(o) for o in result.start_obstacles],
            **({"choices": [{"step": c.index, "kind": c.kind, "object": c.object,
                             "candidate": c.name, "tried": c.tried,
                             "candidates": c.candidates, "details": dict(c.details)}
                            for c in result.choices]} if result.choices else {}),
            "steps": steps}


def obstacle_json(o: Obstacle) -> dict[str, Any]:
    """An obstacle in the requests' form (plan_request.json's ``obstacles``)."""
    return o.to_json()


def task_trajectory(result: TaskResult, sample_rate: float = 100.0) -> dict[str, Any]:
    """The whole task as one ``{joint_names, packed}`` trajectory (execute's form; packed,
    a third the size of points: an 18 s task is ~130 KB)."""
    ts, q, qd, qdd = result.samples(sample_rate)
    return {"joint_names": list(result.joint_names), "packed": pack(ts, q, qd, qdd)}


def twin_body(task: Task, result: TaskResult) -> dict[str, Any]:
    """What a twin simulates of the task (execute's ``twin``): its obstacles, the objects
    it picks up as free bodies where its scene has them, when it grips and lets go."""
    from arduinobot.execution.robots.twin_tasks import task_grasps, task_objects, without
    objects = task_objects(task, result)
    return {"obstacles": [obstacle_json(o) for o in without(result.start_obstacles, objects)],
            "objects": [{"object": obstacle_json(a.shape), "link": a.link,
                         "touch_links": list(a.touch_links), "mass": a.mass}
                        for a in objects],
            "grasps": [{"time": t, "object": o, "hold": h} for t, o, h in task_grasps(result)],
            **({} if task.ground else {"ground": False})}


class TaskService:
    """The ``<prefix>/task`` queryable: each task is planned by a ``task`` job of the
    worker pool (``submit``); this process reads the request, looks named tasks up, asks
    the robot for its state, and relays the execution."""

    def __init__(self, session: zenoh.Session, prefix: str, description: Description, *,
                 submit: Submit, tasks_file: Path | None = None,
                 scene: Callable[[], SceneSnapshot | None] | None = None) -> None:
        self.session, self.prefix, self.description = session, prefix, description
        self.submit = submit
        self.scene = scene  # the kept scene now: a task starts in it, plus its own obstacles
        self.tasks_file = tasks_file if tasks_file is not None else description.config.tasks
        self._entities: list[zenoh.Queryable] = []

    def start(self) -> None:
        key = f"{self.prefix}/task"

        # exact: a wildcard must not move the arm; its own thread: it waits for the
        # pool, then relays a whole execution
        on_query = guarded(key, self._on_task, exact=True, threaded=True, drop=True,
                           internal="unexpected failure in the task service")
        self._entities.append(self.session.declare_queryable(key, on_query, complete=True))
        _log.info("task: key %s (named tasks: %s)", key, self.tasks_file or "none")

    def close(self) -> None:
        for e in self._entities:
            try:
                e.undeclare()
            except zenoh.ZError as err:  # the session's end drops it too
                _log.warning("undeclaring %s failed: %s", e, err)
        self._entities.clear()

    def named(self) -> dict[str, NamedTask]:
        """The service's named tasks (read at each request: edit the file, ask again)."""
        if self.tasks_file is None:
            return {}
        from arduinobot.description.errors import DescriptionError
        try:
            return read_tasks(self.tasks_file)
        except DescriptionError as e:
            raise InvalidRequest(str(e), field="name") from None

    def source(self, body: Mapping[str, Any]) -> tuple[Any, str, str | None]:
        """The request's task in its JSON form (given, or named in tasks.yaml), where its
        fields are (for refusals: ``task``, ``tasks.NAME``) and its name; read by
        :func:`arduinobot.planner.tasks.task_from_mapping` in the worker."""
        if "task" in body:
            return body["task"], "task", None
        key = body.get("name", body.get("number"))
        named = self.named()
        found = find_task(named, key)
        if found is None:
            field = "name" if "name" in body else "number"
            raise InvalidRequest(
                f"no task {key!r} in {self.tasks_file or 'the service (no tasks.yaml)'} "
                f"(tasks: {', '.join(f'{t.number}: {t.name}' if t.number is not None else t.name for t in named.values()) or 'none'})",
                field=field, details={"known": [t.name for t in named.values()]})
        return found.body, f"tasks.{found.name}", found.name

    def _on_task(self, query: zenoh.Query) -> None:
        zb = query.payload
        body = wire.decode("task", zb.to_bytes() if zb is not None else b"")
        outcome = self._plan(self.job(body))
        if isinstance(outcome, Failure):
            reply_failure(query, outcome)
            return
        query.reply(f"{self.prefix}/task", outcome.body, encoding=wire.JSON)
        if outcome.execute is not None:
            self._execute(query, outcome.execute)

    def job(self, body: Mapping[str, Any]) -> dict[str, Any]:
        """The ``task`` job of a decoded request ``body`` (what :func:`answer_task`
        reads); an executed task without a start asks the robot where it is."""
        task, where, name = self.source(body)
        execute = bool(body.get("execute", False))
        start = None
        if execute and not (isinstance(task, Mapping) and task.get("start") is not None):
            start = self._robot_start()  # a task without a start starts where the arm is
        return {
            # a task from the wire names no file of this machine; tasks.yaml's may
            "task": task, "where": where, "name": name, "start": start,
            "files": "task" not in body,
            "trajectories": bool(body.get("trajectories", True)), "execute": execute,
            "start_tolerance": body.get("start_tolerance", 0.01),
            "move_to_start": bool(body.get("move_to_start", False)),
            "on_change": body.get("on_change", DEFAULT_ON_CHANGE),
            "scene_revision": body.get("scene_revision")}

    def _plan(self, job: Mapping[str, Any]) -> Outcome:
        """The task job's outcome, from the pool (which answers every job exactly once:
        planned, refused, or TIMEOUT past its deadline)."""
        return outcome_of(self.submit, "task", job)

    def _robot_start(self) -> dict[str, float]:
        for reply in self.session.get(f"{self.prefix}/robot_state", timeout=30.0):
            if reply.ok is None:
                raise InvalidRequest("the service's robot did not answer its state: give "
                                     "the task a start", field="task.start")
            state = orjson.loads(reply.ok.payload.to_bytes())
            measured = dict(zip(state["name"], map(float, state["position"])))
            # the actuated joints only (mimics follow), clipped into their limits as
            # execute's plan_start does: a servo a hair past its limit is at it
            actuated = self.description.robot.actuated_joints
            lim = self.description.robot.position_limits(actuated)
            return {n: min(max(measured[n], float(lo)), float(hi))
                    for n, (lo, hi) in zip(actuated, lim)}
        raise InvalidRequest("this service drives no robot to start the task from: give "
                             "the task a start", field="task.start")

    def _execute(self, query: zenoh.Query, request: bytes) -> None:
        """Relay ``<prefix>/execute``'s stream for the joined task (``request``, built by
        the worker) to ``query``."""
        key = f"{self.prefix}/task"
        got = False
        for reply in self.session.get(f"{self.prefix}/execute", payload=request,
                                      consolidation=zenoh.ConsolidationMode.NONE,
                                      timeout=STREAM_LIMIT):
            got = True
            if reply.ok is not None:
                query.reply(key, reply.ok.payload.to_bytes(), encoding=wire.JSON)
            else:
                raw = reply.err.payload.to_bytes()
                _log.warning("task: the service's execute refused the task's motion: %s",
                             raw[:300].decode("utf-8", "replace"))
                query.reply_err(raw, encoding=wire.JSON)
        if not got:
            reply_error(query, Code.ROBOT_ERROR, "the service's <prefix>/execute did not "
                       "answer (serve --no-robot?)")


def answer_task(planner: Any, data: Mapping[str, Any], *,
                scene: SceneSnapshot | None) -> Success:
    """A ``task`` job in a worker (``data``: what :meth:`TaskService._on_task` sends):
    the task read, started in the kept ``scene`` (and at ``data["start"]`` if it gives
    none), planned with the worker's ``planner``; the ``planned`` reply (naming the
    scene's revision), and for an executed task the execute request of the whole task,
    both encoded.

    A task's rest replanned after a stop (:mod:`arduinobot.service.execute.task_replan`)
    adds ``carrying`` (the objects held then), ``resting`` (pairs touching then),
    ``exclude`` (kept-scene objects the task moves: its own copies are in the task),
    ``resumed_at`` (the index of its first step in the task as given) and ``source``
    (the task as given, for a later stop's replan).

    Raises:
        SceneConflict: ``data["scene_revision"]`` pins a revision the scene has left.
        PlanningError: the task's refusal (a field, a step that failed: its own code).
    """
    from arduinobot.planner.tasks import plan_task, task_from_mapping
    from arduinobot.service.task.pieces import task_pieces
    task = task_from_mapping(data["task"], where=data["where"], name=data["name"],
                             files=bool(data.get("files", False)))
    scene_ids = [o.id for o in (scene.obstacles if scene is not None else ())]
    exclude = {str(i) for i in data.get("exclude") or ()}
    if exclude and scene is not None:  # where the task has them: in its own obstacles
        scene = replace(scene, obstacles=tuple(o for o in scene.obstacles
                                               if o.id not in exclude))
    obstacles, revision = with_scene(scene, {"scene_revision": data.get("scene_revision")},
                                     task.obstacles)
    task = replace(task, obstacles=obstacles,
                   clouds=scene.clouds if scene is not None else (),
                   carrying=_carrying(data.get("carrying") or (),
                                      files=bool(data.get("files", False))),
                   resting=tuple((str(a), str(b)) for a, b in data.get("resting") or ()))
    if data.get("start") is not None and task.start is None:
        task = _with_start(task, data["start"])
    result = plan_task(planner, task)
    planned = planned_body(result, name=task.name,
                           trajectories=bool(data.get("trajectories", True)))
    body = wire.encode({**planned, "scene_revision": revision})
    if not data.get("execute"):
        return Success(body)
    return Success(body, execute=wire.encode({
        "trajectory": task_trajectory(result),
        "start_tolerance": data.get("start_tolerance", 0.01),
        "move_to_start": bool(data.get("move_to_start", False)),
        "on_change": data.get("on_change", DEFAULT_ON_CHANGE),
        "twin": twin_body(task, result),
        # each step's world along the motion: a scene change re-checks the rest by it,
        # and a stop replans the remaining steps of the task as given (``replan``)
        "task": {**task_pieces(task, result, scene_ids=scene_ids, moved=sorted(exclude),
                               first=int(data.get("resumed_at", 0))),
                 "replan": data.get("source") or {
                     "task": data["task"], "where": data["where"], "name": data["name"],
                     "files": bool(data.get("files", False)),
                     "start_tolerance": data.get("start_tolerance", 0.01)}}}))


def _carrying(items: Any, *, files: bool) -> tuple[AttachedObject, ...]:
    """A resumed task's carried objects (``carrying``); without ``files`` none may name
    a file of this machine (they came back on the wire)."""
    out = []
    for i, a in enumerate(items):
        if not files and isinstance(a, Mapping) and isinstance(a.get("object"), Mapping):
            refuse_files(a["object"], where=f"carrying[{i}].object")
        out.append(AttachedObject.from_mapping(a, where=f"carrying[{i}]"))
    return tuple(out)


def _with_start(task: Task, start: Mapping[str, float]) -> Task:
    return replace(task, start=dict(start))


def task_extension(*, tasks_file: str | Path | None = None) -> Callable[[Host], TaskService]:
    """An extension (:mod:`arduinobot.service.extension`) serving ``<prefix>/task``, its
    tasks planned through the host's pool, each starting in the host's kept scene."""
    def make(host: Host) -> TaskService:
        svc = TaskService(host.session, host.prefix, host.description, submit=host.submit,
                          tasks_file=Path(tasks_file) if tasks_file else None,
                          scene=host.scene)
        svc.start()
        return svc
    return make


def task_number_known(description: Description, tasks_file: str | Path | None,
                      number: int) -> bool:
    """Whether the service's tasks.yaml (``tasks_file``, else the MoveIt config's) names
    a task ``number``."""
    path = Path(tasks_file) if tasks_file else description.config.tasks
    if path is None:
        return False
    return any(t.number == number for t in read_tasks(path).values())
