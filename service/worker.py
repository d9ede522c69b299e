"""A worker process's job loop: decode, validate and answer jobs sent over a socket.

Workers are forked, already warm, from :mod:`service.zygote` (which builds the model
once); :func:`serve_jobs` is what each fork runs. Validation runs here, not on the
serving process's Zenoh thread, so a request that is slow to validate holds one worker
until its deadline (then the worker is killed and replaced), never the whole service.

Protocol (``conn`` is a :class:`multiprocessing.connection.Connection`):

- in: ``(job_id, kind, payload, base_deadline)`` where ``payload`` is the raw request
  bytes (decoded here with :func:`service.wire.decode`) or an already validated dict,
  and ``base_deadline`` is the arrival time plus the service's timeout, on
  :func:`time.monotonic` (the same clock in every process); ``None`` to stop;
- out: ``("taken", job_id)`` on receipt (a worker that dies before it did not die of
  this job), ``("deadline", job_id, seconds)`` once the request is valid (plans add
  their ``planning_time``), then ``(job_id, "ok", json_bytes)`` or
  ``(job_id, "err", code, message, details)``.
"""

from __future__ import annotations

import logging
import time
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

from description import load_description
from planner.errors import PlanningError

from . import wire
from .disk_cache import DiskCache
from .handlers import Handlers

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
    #: cache folder, see :mod:`service.disk_cache`; "" to keep nothing)
    cache_dir: str | None = None

    def cache(self) -> DiskCache | None:
        return None if self.cache_dir == "" else DiskCache(self.cache_dir)

    def load(self):  # -> Description
        return load_description(self.path, package_dirs=list(self.package_dirs),
                                args=dict(self.args), moveit_config=self.moveit_config,
                                srdf=self.srdf, joint_limits=self.joint_limits)


def build_handlers(spec: DescriptionSpec) -> Handlers:
    """Load the robot, build the planner and plan one warm-up motion (seconds on CAD
    meshes: done once per zygote, never per worker)."""
    t0 = time.perf_counter()
    _log.info("loading the robot")
    description = spec.load()
    _log.info("building the planner: collision geometry, limits, dynamics")
    handlers = Handlers(description, cache=spec.cache())
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
    """When a valid job must be answered [monotonic s]: plans add their planning_time."""
    if kind != "plan":
        return base_deadline
    return base_deadline + float(data.get("planning_time", DEFAULT_PLANNING_TIME))


def serve_jobs(conn: Connection, handlers: Handlers) -> None:
    """Answer jobs until ``None`` or EOF (see the module's protocol)."""
    while True:
        try:
            msg = conn.recv()
        except EOFError:
            return
        if msg is None:
            return
        job_id, kind, payload, base_deadline = msg
        conn.send(("taken", job_id))
        try:
            data = wire.decode(kind, payload) if isinstance(payload, (bytes, str)) \
                else payload
            deadline = job_deadline(kind, data, base_deadline)
            conn.send(("deadline", job_id, deadline))
            body = handlers.handle(kind, data)
        except PlanningError as e:
            conn.send((job_id, "err", e.code, e.message, e.details))
        except MemoryError:
            # the heap may be half-built: answer, then leave so a fresh fork takes over
            conn.send((job_id, "err", "RESOURCE_LIMIT", "the request needed more memory "
                       "than a worker may use", {"exception": "MemoryError"}))
            return
        except Exception as e:  # noqa: BLE001 -- a bug: INTERNAL, the worker lives on
            _log.error("job %s (%s) failed:\n%s", job_id, kind, traceback.format_exc())
            conn.send((job_id, "err", "INTERNAL", f"{type(e).__name__}: {e}",
                       {"exception": type(e).__name__}))
        else:
            # encoded here, in parallel across workers, not in the serving process
            conn.send((job_id, "ok", wire.encode({**body, "request_id": job_id},
                                                 finite=kind == "plan")))
