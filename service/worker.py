"""The worker process: load the description once, then answer jobs over a pipe.

Started by :class:`service.pool.WorkerPool` with the forkserver (or spawn) start method,
never by forking a process that holds a Zenoh session.
"""

from __future__ import annotations

import logging
import os
import signal
import time
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection

from description import load_description
from planner.errors import PlanningError

from . import wire
from .disk_cache import DiskCache
from .handlers import Handlers

_log = logging.getLogger(__name__)


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


def worker_main(conn: Connection, spec: DescriptionSpec, log_level: int) -> None:
    """Serve jobs ``(job_id, kind, data)`` until ``None`` or EOF.

    Sends ``("ready", pid)`` once warmed up (or ``("failed", message)``), then per job
    ``(job_id, "ok", json_bytes)`` (the reply, request_id included) or
    ``(job_id, "err", code, message, details)``.
    """
    # Ctrl-C reaches the whole process group: the parent shuts workers down itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.basicConfig(level=log_level,
                        format="%(asctime)s %(levelname)s %(name)s[%(process)d]: %(message)s")
    from planner.planning import set_ompl_log_level
    set_ompl_log_level("info" if log_level <= logging.INFO else "none")
    # say what a slow start is doing: CAD meshes make the geometry the long part
    logging.getLogger("service").setLevel(min(logging.INFO, log_level))
    t0 = time.perf_counter()
    try:
        _log.info("loading the robot")
        description = spec.load()
        _log.info("building the planner: collision geometry, limits, dynamics")
        handlers = Handlers(description, cache=spec.cache())
        handlers.warm_up()
    except Exception as e:  # noqa: BLE001 -- reported to the parent, which refuses to start
        conn.send(("failed", f"{type(e).__name__}: {e}"))
        return
    _log.info("ready in %.1f s", time.perf_counter() - t0)
    conn.send(("ready", os.getpid()))
    while True:
        try:
            msg = conn.recv()
        except EOFError:
            return
        if msg is None:
            return
        job_id, kind, data = msg
        try:
            body = handlers.handle(kind, data)
        except PlanningError as e:
            conn.send((job_id, "err", e.code, e.message, e.details))
        except Exception as e:  # noqa: BLE001 -- a bug: INTERNAL, the worker lives on
            _log.error("job %s (%s) failed:\n%s", job_id, kind, traceback.format_exc())
            conn.send((job_id, "err", "INTERNAL", f"{type(e).__name__}: {e}",
                       {"exception": type(e).__name__}))
        else:
            # encoded here, in parallel across workers, not in the serving process
            conn.send((job_id, "ok", wire.encode({**body, "request_id": job_id},
                                                 finite=kind == "plan")))
