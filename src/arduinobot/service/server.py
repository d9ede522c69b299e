"""The Zenoh service: queryables under a prefix, a liveliness token, a worker pool.

The keys and their replies: the README's key table. The work kinds (:data:`WORK_KINDS`)
are answered by the pool, the others at once; each is declared complete under
``<p>/<kind>`` (shared) and ``<p>/instance/<id>/<kind>`` (this instance only).
"""

from __future__ import annotations

import contextlib
import gc
import itertools
import json
import logging
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import zenoh

from arduinobot.contract import wire
from arduinobot.contract.errors import PlanningError, ShuttingDown
from arduinobot.contract.zconfig import (
    DEFAULT_ENDPOINT,
    DEFAULT_PREFIX,
    Mode,
    check_prefix,
    zenoh_config,
)
from arduinobot.scene.state import SceneSnapshot
from arduinobot.service import hoptrace
from arduinobot.service.extension import Extension, Host
from arduinobot.service.messages import Failure, JobKind, Outcome, Success
from arduinobot.service.peers import refuse_peer_instances
from arduinobot.service.perceive.perceive_service import ImageSource, perceive_extension
from arduinobot.service.plan.bodies import description_body
from arduinobot.service.process.heap_trim import HeapTrimmer
from arduinobot.service.process.job import SHUTTING_DOWN, Job
from arduinobot.service.process.memtrace import MemTrace, count_live
from arduinobot.service.process.pool import WorkerPool
from arduinobot.service.process.worker import DescriptionSpec
from arduinobot.service.queries import guarded, reply_failure
from arduinobot.service.scene.carry import PooledFrames
from arduinobot.service.scene.sync import SceneService
from arduinobot.service.task.task_service import task_extension

_log = logging.getLogger(__name__)

VERSION = "1"
WORK_KINDS = ("plan", "fk", "ik", "check")
SCENE_KINDS = ("plan", "check")  # the work kinds answered against the kept scene
#: what the pool does: the work kinds, the tasks of <prefix>/task, and the link poses and
#: contacts of the kept scene's attach and detach
INFO_KINDS = ("description", "health", "schema")
#: a worker's default memory cap [bytes]. Measured resident sets: 223 MiB ready and
#: 323 MiB after 20 plans on the shipped arm, 348 and 554 MiB on the course workspace's
#: CAD meshes; 2 GiB is ~4x the largest
DEFAULT_MEMORY_CAP = 2 * 2**30


@dataclass(frozen=True)
class ServeOptions:
    """Everything ``arduinobot serve`` takes.

    Attributes:
        timeout: a request's deadline after arrival [s] (plan requests add their
            planning_time); past it the request is answered TIMEOUT.
        queue_size: requests that may wait for a worker (default 4 per worker).
    """

    prefix: str = DEFAULT_PREFIX
    mode: Mode | None = "peer"
    listen: Sequence[str] | None = (DEFAULT_ENDPOINT,)
    connect: Sequence[str] | None = None
    config_file: str | None = None
    multicast_scouting: bool = False
    description: DescriptionSpec = field(default_factory=DescriptionSpec)
    workers: int = field(default_factory=lambda: os.cpu_count() or 1)
    queue_size: int | None = None
    timeout: float = 30.0
    #: a worker's largest resident set [bytes] before it is killed and its request
    #: answered RESOURCE_LIMIT (None: no cap); see DEFAULT_MEMORY_CAP
    memory_cap: int | None = DEFAULT_MEMORY_CAP
    #: on close, how long requests already in a worker may still take [s]
    grace: float = 2.0
    #: Zenoh's shared-memory transport with clients on this host (off: see
    #: :func:`arduinobot.contract.zconfig.zenoh_config`)
    shared_memory: bool = False
    #: more queryables on the service's session, each built once it is open:
    #: ``make(host) -> object with close()`` (:mod:`arduinobot.service.extension`;
    #: ``arduinobot serve`` adds ``<prefix>/execute``); closed first on shutdown
    extensions: Sequence[Extension] = ()
    #: where this instance keeps the scene (None: arduinobot.service.scene.file.default_scene_file)
    scene_file: str | None = None
    #: the named tasks of <prefix>/task (None: the MoveIt config's tasks.yaml)
    tasks_file: str | None = None
    #: the latest image of a camera topic, for <prefix>/perceive's image "topic" (``serve
    #: --ros2 --camera-topic``: :class:`arduinobot.service.ros2_inputs.TopicCamera`)
    camera: ImageSource | None = None

    def __post_init__(self) -> None:
        check_prefix(self.prefix)  # a wildcard prefix would answer every other prefix


def _package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("arduinobot")
    except PackageNotFoundError:
        return "unknown"


class PlannerService:
    """Start with :meth:`start`, stop with :meth:`close`.

    The pool starts (and every worker loads the description) before the Zenoh session
    opens, so no process is ever forked from one holding a session.
    """

    def __init__(self, options: ServeOptions) -> None:
        self.options = options
        self.pool: WorkerPool | None = None
        self.session: zenoh.Session | None = None
        self.instance = ""
        self._entities: list[Any] = []  # per-instance queryables, liveliness token
        self._shared: list[Any] = []  # queryables on the shared keys
        self._ids = itertools.count(1)
        self._started = time.monotonic()
        self._static: dict[str, bytes] = {}
        self._config: dict[str, str | None] = {}
        self._extensions: list[Any] = []
        self._memtrace: MemTrace | None = None
        self._trimmer = HeapTrimmer()
        self.scene: SceneService | None = None

    def start(self) -> None:
        o = self.options
        qsize = o.queue_size if o.queue_size is not None else 4 * o.workers
        # the pool's forkserver imports the planner meanwhile; no worker starts yet
        self.pool = WorkerPool(o.description, workers=o.workers, queue_size=qsize,
                               memory_cap=o.memory_cap)
        desc = o.description.load()  # fails here, clearly, before any worker starts
        self._static["description"] = wire.encode(description_body(desc))
        self._static["schema"] = wire.encode({"version": VERSION, **wire.all_schemas(),
                                              "robot": desc.summary()})
        self._config = desc.config.to_json()
        self._memtrace = MemTrace.from_env(counts=self._held)
        self._trimmer.start()
        try:
            cfg = zenoh_config(mode=o.mode, listen=o.listen, connect=o.connect,
                               config_file=o.config_file,
                               multicast_scouting=o.multicast_scouting,
                               shared_memory=o.shared_memory)
            self.session = zenoh.open(cfg)
            self.instance = str(self.session.zid())
            p = o.prefix
            # before the workers' seconds of warm-up, and before it answers anything
            refuse_peer_instances(self.session, p)
            self.pool.start()
            # the kept scene first: caught up with the other instances before any plan
            # attach's frames and the meshes' parse in a worker (see scene/carry.py)
            pooled = PooledFrames(desc, submit=self.submit)
            self.scene = SceneService(self.session, p, self.instance,
                                      tuple(desc.robot.links), scene_file=o.scene_file,
                                      description=desc, robot=pooled, meshes=pooled)
            self.scene.start()
            for kind in (*WORK_KINDS, *INFO_KINDS):
                for key, held in ((f"{p}/{kind}", self._shared),
                                  (f"{p}/instance/{self.instance}/{kind}", self._entities)):
                    held.append(self.session.declare_queryable(
                        key, self._callback(kind, key), complete=True))
            self._entities.append(
                self.session.liveliness().declare_token(f"{p}/alive/{self.instance}"))
            host = Host(self.session, p, desc, self.submit, self._submit_plan,
                        self._scene_now)
            # <prefix>/task (the service's own): tasks planned by the pool, executed
            # through <prefix>/execute; <prefix>/perceive: objects seen in a camera image
            # (OpenCV imported on the first request)
            for make in (*o.extensions, task_extension(tasks_file=o.tasks_file),
                         perceive_extension(spec=o.description, camera=o.camera)):
                self._extensions.append(make(host))
        except Exception:
            self.close()
            raise
        self._started = time.monotonic()
        # what start built (the description, schemas, the scene, Zenoh's objects) lives
        # as long as the service: out of the collector's sight, so no full collection
        # walks it on a request's time (the zygote does the same for its model)
        gc.collect()
        gc.freeze()
        # where clients reach it: what a user must pass as --connect
        listen, connect = _endpoints(cfg, "listen"), _endpoints(cfg, "connect")
        where = f"listening on {', '.join(listen)}" if listen else "no listener"
        if connect:
            # the endpoints are what was asked; whether anything answers there is Zenoh's
            # sessions (it keeps trying): say which, not "connected" when nothing listens
            info = self.session.info
            reached = len(list(info.routers_zid())) + len(list(info.peers_zid()))
            where += (f", connecting to {', '.join(connect)} ({reached} router(s)/peer(s) "
                      "reached)" if reached else
                      f", connecting to {', '.join(connect)} (nothing answers there yet; "
                      "Zenoh keeps trying)")
        _log.info("arduinobot service ready: instance %s, %d workers, robot '%s', %s; "
                  "serving %s (and %s/instance/%s/*), liveliness %s/alive/%s", self.instance,
                  o.workers, desc.robot.name, where,
                  ", ".join(f"{p}/{k}" for k in (*WORK_KINDS, *INFO_KINDS)), p, self.instance,
                  p, self.instance)

    def close(self) -> None:
        """Hand the keys over, answer what is in flight, then close the session.

        Other instances take the shared keys as soon as this session closes; until then
        new work is answered SHUTTING_DOWN (coded: a client may retry at once), waiting
        requests too, and requests in a worker get ``options.grace`` seconds.
        """
        while self._extensions:  # e.g. stops a moving arm smoothly, first
            self._extensions.pop().close()
        # the liveliness token first: clients that pick instances stop picking this one
        for e in reversed(self._entities):
            with contextlib.suppress(zenoh.ZError):  # already gone with the session
                e.undeclare()
        self._entities.clear()
        if self.pool is not None:
            self.pool.close(grace=self.options.grace)
            self.pool = None
        if self.scene is not None:
            self.scene.close()
            self.scene = None
        if self.session is not None:
            # The shared queryables are NOT undeclared one by one: with zenoh 1.10, an
            # explicit undeclare of a complete queryable makes a router drop its route to
            # the other instances' complete queryables on the same key (gets then time
            # out for good), while closing the session hands the key over at once, as a
            # crash does. tests/service/test_service_cluster.py holds it.
            self.session.close()
            self.session = None
        self._shared.clear()
        self._trimmer.stop()
        if self._memtrace is not None:
            self._memtrace.close()
            self._memtrace = None

    def health(self) -> dict[str, Any]:
        st = self.pool.status() if self.pool is not None else {"load": 0.0}
        # the kept scene's revision: a follower polls this, not the whole scene
        scene = self.scene.state.revision if self.scene is not None else 0
        return {"version": _package_version(), "api": VERSION, "instance": self.instance,
                "prefix": self.options.prefix, "uptime": time.monotonic() - self._started,
                "workers": self.options.workers, "config": self._config,
                "scene_revision": scene, **st}

    # -- queries -----------------------------------------------------------------------
    def _callback(self, kind: str, key: str):
        # on Zenoh's thread: only cheap checks here, planning goes to the pool; a
        # wildcard gets no reply from a work key (see arduinobot.service.keyguard)
        return guarded(key, lambda query: self._on_query(kind, key, query),
                       exact=kind in WORK_KINDS)

    def _on_query(self, kind: str, key: str, query: zenoh.Query) -> None:
        t_in = hoptrace.now() if hoptrace.ON else 0.0
        if kind in self._static:
            query.reply(key, self._static[kind], encoding=wire.JSON)
            return
        if kind == "health":
            query.reply(key, wire.encode(self.health()), encoding=wire.JSON)
            return
        request_id = f"{self.instance[:8]}-{next(self._ids)}"
        pool = self.pool
        try:
            if pool is None:  # closed (a closing pool answers SHUTTING_DOWN itself)
                raise ShuttingDown(SHUTTING_DOWN)
            zb = query.payload
            if zb is not None and len(zb) > wire.MAX_PAYLOAD:  # refuse before copying it
                wire.check_size(len(zb))
            if kind in SCENE_KINDS and self.scene is not None:
                self.scene.check_current()  # never against a scene it knows is stale
        except PlanningError as e:
            if pool is not None:  # counted as the pool counts the requests it refuses
                pool.count("received")
                pool.count(e.code.value)
            reply_failure(query, Failure.of(e, request_id=request_id))
            return
        # Decoding and validation run in a worker (wire.decode there), not on this
        # thread: Zenoh calls every queryable's callback on one thread, so a request
        # slow to validate would hold every other; a worker is held only to its deadline.
        raw = zb.to_bytes() if zb is not None else b""
        trace = {"callback": t_in} if hoptrace.ON else None

        def respond(outcome: Outcome, query: zenoh.Query = query) -> None:
            if isinstance(outcome, Success):  # the worker encoded it, request_id included
                query.reply(key, outcome.body, encoding=wire.JSON)
            else:
                reply_failure(query, outcome)
            if trace is not None:
                trace["replied"] = hoptrace.now()
            query.drop()  # the reply is final: let the querier's get finish now
            if trace is not None:
                trace["final"] = hoptrace.now()
                hoptrace.write(request_id, kind, trace)

        job = Job(kind, raw, request_id, time.monotonic() + self.options.timeout, respond,
                  scene=self._scene_now())
        if trace is not None:
            job.trace = trace
            trace["queued"] = hoptrace.now()
        pool.submit(job)

    def _submit_plan(self, data: dict[str, Any], respond: Callable[[Outcome], None]
                     ) -> None:
        """A plan job for an extension's own planning, through the same pool."""
        self.submit("plan", data, respond)

    def submit(self, kind: JobKind, data: Mapping[str, Any],
               respond: Callable[[Outcome], None]) -> None:
        """A job of ``kind`` with a valid request ``data`` through the pool, against the
        kept scene now; ``respond`` gets its one outcome (a ``task`` job: see
        :mod:`arduinobot.service.task.task_service`).

        Raises:
            ShuttingDown: the pool is closed.
            SceneUnavailable: (BUSY) the kept scene is catching up (a plan, check or task).
        """
        pool = self.pool
        if pool is None:  # closed: as _on_query answers a query that arrives then
            raise ShuttingDown(SHUTTING_DOWN)
        if kind in (*SCENE_KINDS, "task", "recheck") and self.scene is not None:
            self.scene.check_current()  # (a moving arm's recheck: it stops instead)
        pool.submit(Job(kind, data, f"{self.instance[:8]}-{next(self._ids)}",
                        time.monotonic() + self.options.timeout, respond,
                        scene=self._scene_now()))

    def _scene_now(self) -> SceneSnapshot | None:
        """The kept scene a request arriving now is answered against."""
        return self.scene.state.snapshot if self.scene is not None else None

    def _held(self) -> dict[str, int]:
        """Live jobs and what the pool holds (the memory probe's numbers)."""
        pool = self.pool
        return {**(pool.held() if pool is not None else {}), **count_live((Job,))}


def _endpoints(cfg: zenoh.Config, what: str) -> list[str]:
    """The ``listen`` or ``connect`` endpoints of ``cfg`` for its mode (a config may give
    one list, or one per mode)."""
    eps = json.loads(cfg.get_json(f"{what}/endpoints"))
    if isinstance(eps, dict):
        eps = eps.get(json.loads(cfg.get_json("mode")) or "peer", [])
    return [str(e) for e in eps or ()]

