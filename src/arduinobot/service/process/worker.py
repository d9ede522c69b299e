"""A worker process's job loop: decode, validate and answer jobs sent over a socket.

:func:`serve_jobs` is what each fork of :mod:`arduinobot.service.process.zygote` runs (why validation runs
here: :meth:`arduinobot.service.server.PlannerService._on_query`); what crosses the socket, and in
which order: :mod:`arduinobot.service.messages`.
"""

from __future__ import annotations

import logging
import time
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any, cast

import orjson

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import PlanningError
from arduinobot.contract.ranges import RANGES
from arduinobot.description import load_description
from arduinobot.service import hoptrace
from arduinobot.service.messages import (
    HELD_SCENE,
    Deadline,
    Done,
    Failure,
    JobMsg,
    Success,
    TakenMark,
    receive,
)
from arduinobot.service.process.disk_cache import DiskCache
from arduinobot.service.process.heap_trim import IdleTrim

if TYPE_CHECKING:  # the serving process imports this module, never the planner
    from arduinobot.service.plan.handlers import Handlers

_log = logging.getLogger(__name__)

#: a plan request's planning_time when it gives none [s] (the schema's default)
DEFAULT_PLANNING_TIME = 1.0


@dataclass(frozen=True)
class DescriptionSpec:
    """How a worker loads the robot: the arguments of :func:`description.load_description`."""

    path: str | None = None
    package_dirs: Sequence[str] = ()
    args: Mapping[str, str] = field(default_factory=dict)
    moveit_config: str | None = None
    srdf: str | None = None
    joint_limits: str | None = None
    #: where to keep what is derived from the robot between starts (None: the user's
    #: cache folder, see :mod:`arduinobot.service.process.disk_cache`; "" to keep nothing)
    cache_dir: str | None = None

    def load(self):  # -> Description
        return load_description(self.path, package_dirs=list(self.package_dirs),
                                args=dict(self.args), moveit_config=self.moveit_config,
                                srdf=self.srdf, joint_limits=self.joint_limits)


def build_handlers(spec: DescriptionSpec) -> Handlers:
    """Load the robot, build the planner and plan one warm-up motion (seconds on CAD
    meshes: done once per zygote, never per worker)."""
    from arduinobot.service.plan.handlers import (
        Handlers,  # the planner: in the zygote, not the serving process
    )

    t0 = time.perf_counter()
    _log.info("loading the robot")
    description = spec.load()
    _log.info("building the planner: collision geometry, limits, dynamics")
    handlers = Handlers(description,
                        cache=None if spec.cache_dir == "" else DiskCache(spec.cache_dir))
    handlers.warm_up()
    for kind in ("plan", "fk", "ik", "check"):
        # builds and caches each request validator now (tens of ms), not in every fork
        try:
            wire.validate(kind, {})
        except PlanningError:
            pass  # {} is not a valid plan request: only the built validator matters
    _log.info("ready in %.1f s", time.perf_counter() - t0)
    return handlers


def job_deadline(kind: str, data: Mapping[str, Any], base_deadline: float) -> float:
    """When a valid job must be answered [monotonic s]: plans add their planning_time,
    tasks every step's."""
    if kind == "task":
        return base_deadline + task_planning_time(data.get("task"))
    plan = float(data.get("planning_time", DEFAULT_PLANNING_TIME)) if kind == "plan" else 0.0
    return base_deadline + plan


def task_planning_time(task: Any) -> float:
    """The sum of a task's steps' planning times [s] (a step's own, else the task's,
    else the default), from its JSON form before it is read: a malformed value counts
    as the default (the worker refuses it, naming its field)."""
    steps = task if isinstance(task, list) else \
        task.get("steps") if isinstance(task, Mapping) else None
    if not isinstance(steps, list):
        return DEFAULT_PLANNING_TIME
    whole = _seconds(task.get("planning_time") if isinstance(task, Mapping) else None,
                     DEFAULT_PLANNING_TIME)
    return sum(_seconds(s.get("planning_time") if isinstance(s, Mapping) else None, whole)
               for s in steps)


def _seconds(value: Any, default: float) -> float:
    return float(value) if value in RANGES["planning_time"] else default


def serve_jobs(conn: Connection, handlers: Handlers, taken: TakenMark) -> None:
    """Answer jobs until :class:`~arduinobot.service.messages.Stop` or EOF (see the module), each
    marked ``taken`` as it arrives."""
    held: Any = None  # the last scene snapshot sent (a job may say it uses it again)
    trim = IdleTrim()  # what a job freed, given back while no other waits
    while (job := receive(conn)) is not None:
        if not isinstance(job, JobMsg):
            raise TypeError(f"a worker takes JobMsg, not {type(job).__name__}")
        stamps: list[float] | None = [hoptrace.now()] if hoptrace.ON else None
        taken.mark(job.seq)
        if isinstance(job.scene, str) and job.scene == HELD_SCENE:
            if held is None:  # the slot's bookkeeping is wrong: a bug, never a guess
                raise RuntimeError(f"job {job.job_id} refers to a held scene; none is held")
            job = replace(job, scene=held)
        elif job.scene is not None:
            held = job.scene
        outcome, last = _answer(conn, job, handlers, stamps)
        conn.send(Done(job.job_id, outcome, tuple(stamps or ())))
        if last:
            return
        del job, outcome  # freed before the trim, not held until the next job
        trim.after_job(busy=conn.poll(0))


def _answer(conn: Connection, job: JobMsg, handlers: Handlers,
            stamps: list[float] | None = None) -> tuple[Success | Failure, bool]:
    """The job's outcome, and whether this worker must end after sending it (``stamps``:
    the hop trace's, appended to when tracing)."""
    try:
        # the pool carries work kinds, tasks and frames (the server answers the others)
        raw = isinstance(job.payload, (bytes, str))
        data = wire.decode(cast("wire.Kind", job.kind), job.payload) \
            if isinstance(job.payload, (bytes, str)) else job.payload
        if stamps is not None:
            stamps.append(hoptrace.now())
        deadline = job_deadline(job.kind, data, job.base_deadline)
        if raw and deadline != job_deadline(job.kind, {}, job.base_deadline):
            # the pool's provisional deadline is another: say it (one message, and one
            # wake of the pool's thread, fewer for a request at the default; a job
            # submitted valid had its own deadline from the start)
            conn.send(Deadline(job.job_id, deadline))
        # encoded here, in parallel across workers, not in the serving process
        if job.kind == "frames":  # for the kept scene: see arduinobot.service.scene.carry
            body = handlers.frames(data)
            if stamps is not None:
                stamps.append(hoptrace.now())
            out = Success(orjson.dumps(body))
        elif job.kind == "task":  # its reply and execute request: see arduinobot.service.task.task_service
            out = handlers.task(data, scene=job.scene)
            if stamps is not None:
                stamps.append(hoptrace.now())
        elif job.kind == "plan":
            # from the sample arrays to bytes, no Python object per sample (imported here:
            # the serving process imports this module, and never the planner)
            from arduinobot.service.plan.plan_io import plan_reply
            result = handlers.solve(data, scene=job.scene)
            if stamps is not None:
                stamps.append(hoptrace.now())
            out = Success(plan_reply(
                result, job.job_id, scene_revision=0 if job.scene is None else job.scene.revision,
                trajectory_format=data.get("trajectory_format", "points"),
                clouds=None if job.scene is None else job.scene.assumptions()))
        else:
            body = handlers.handle(job.kind, data, scene=job.scene)
            if stamps is not None:
                stamps.append(hoptrace.now())
            out = Success(wire.encode({**body, "request_id": job.job_id}))
        if stamps is not None:
            stamps.append(hoptrace.now())
        return out, False
    except PlanningError as e:
        return Failure.of(e), False
    except MemoryError:
        # the heap may be half-built: answer, then leave so a fresh fork takes over
        return Failure(Code.RESOURCE_LIMIT, "the request needed more memory than a worker "
                       "may use", {"exception": "MemoryError"}), True
    except Exception as e:  # noqa: BLE001 -- a bug: INTERNAL, the worker lives on
        _log.error("job %s (%s) failed:\n%s", job.job_id, job.kind, traceback.format_exc())
        return Failure(Code.INTERNAL, f"{type(e).__name__}: {e}",
                       {"exception": type(e).__name__}), False
