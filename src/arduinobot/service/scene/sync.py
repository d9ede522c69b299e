"""The kept scene under a prefix, shared by every instance through Zenoh, kept on disk.

Keys (``<p>`` the prefix, ``<id>`` an instance's Zenoh id):

- ``<p>/scene`` and ``<p>/instance/<id>/scene`` (query, no payload): the scene,
  ``{"revision", "objects", "attached"}``;
- ``<p>/scene/apply`` and ``<p>/instance/<id>/scene/apply`` (query): a change
  (``scene_apply_request.json``), answered ``{"revision", "objects", "attached"}`` (and
  ``state_source`` for an attach or detach) once applied, kept on disk and replicated,
  or refused with a coded error and nothing changed;
- ``<p>/scene/changes`` (publication): ``{"revision", "added", "removed", "attached",
  "detached", "cleared", "arrived"}`` per applied revision, for whoever watches
  (``arrived``: when the apply reached the leading instance, wall clock [s since the
  epoch]: a moving arm's reaction is timed from it, :mod:`arduinobot.service.execute.react`);
- ``<p>/instance/<id>/scene/lead``, ``.../scene/sync`` and ``.../scene/ready``, liveliness
  ``<p>/scene/member/<id>``: between instances only.

One writer at a time: every instance sends an apply to the leader, the live instance
(liveliness ``<p>/alive/<id>``) with the smallest id that answers it is ready
(:mod:`arduinobot.service.scene.election`: a token alone, of a hung process or of
something that is no ``serve``, leads nothing), on its ``scene/lead`` key; the
leader applies changes one after another (so ``if_revision`` means what it says), writes
its file, sends the change to every other member's ``scene/sync`` (one exact query each)
and waits for their answers, and only then acknowledges. The keys that change the scene
answer exact queries only, as the work keys do (:mod:`arduinobot.service.keyguard`). So a change acknowledged through any instance
is on the leader's disk and in every live instance's scene: the next plan through any of
them uses it, and killing any instance loses nothing. An instance that missed changes
(down, or late) fetches the whole scene from the sender; a new instance takes the newest
scene among its file and the live instances' before it serves anything.

An instance never plans on a scene it knows may be stale: when another member's token
comes back after it went (that instance, or this one, back from a pause or a partition
past Zenoh's lease, which the leader's acknowledgements did not wait for) or a change from the leader could
not be kept (a full disk), it fetches the newest scene of the live instances, and until
that succeeds its plans and checks are refused ``BUSY`` (``details.reason``
``catching_up``; retry). An acknowledgement names the members that did not take the
change (``not_taken_by``): they catch up the same way.

Every change carries an ``apply_id`` (the client's, else one given by the instance that
takes it): the leader and every member that took the change remember the last
:data:`REMEMBERED_APPLIES` ids with the revision each made, so a retry (a lost reply, or
the instance that took it re-sending to the next leader after the old one died having
applied and replicated it) is answered ``already_applied`` with that revision and changes
nothing, instead of "duplicate id" for a change that was made. An instance that fetched
a whole scene knows only the ids it took itself.

An attach or detach gets the robot's state from the instance that takes the apply, before
the change goes to the leader (:mod:`arduinobot.service.scene.apply`; ``state_source`` in the reply
says where it came from).
"""

from __future__ import annotations

import concurrent.futures
import itertools
import logging
import os
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest, SceneConflict
from arduinobot.description import Description
from arduinobot.scene.builder import MeshStore, SceneBuilder
from arduinobot.scene.change import apply, restore
from arduinobot.scene.frames import Frames
from arduinobot.scene.state import SceneState, StateSource
from arduinobot.service.queries import answering, guarded, reply_error
from arduinobot.service.scene.apply import (
    MAX_APPLY_PAYLOAD,
    SceneUnavailable,
    decode_apply,
    with_robot_state,
)
from arduinobot.service.scene.election import Election
from arduinobot.service.scene.file import (
    SceneFile,
    collect_meshes,
    default_scene_file,
    foreign_owner,
    mesh_dir_for,
    object_named,
    scene_owner,
)
from arduinobot.service.scene.identity import EncodedScenes
from arduinobot.service.scene.members import Instances
from arduinobot.service.scene.turns import TURN_TIME, Turns

_log = logging.getLogger(__name__)

#: How long the leader waits for the other instances to take a change [s].
REPLICATE_TIMEOUT = 10.0
#: How long a forwarded apply may take at the leader [s] (mesh decoding included).
FORWARD_TIMEOUT = 30.0
#: How long an apply waits for a leader that answers (one that died hands over once its
#: liveliness token is gone) [s].
LEADER_WAIT = 10.0
#: How long a starting instance waits for the live instances' scenes [s].
CATCH_UP_TIMEOUT = 5.0
#: How many applied ``apply_id`` s an instance remembers (oldest forgotten first).
REMEMBERED_APPLIES = 4096
#: [s] between attempts to catch up that failed (no answer, a full disk)
CATCH_UP_RETRY = 1.0


class SceneService:
    """One instance's part of the shared scene (see the module). :meth:`start` before the
    instance serves plans (it catches up first), :meth:`close` before its session closes.

    Args:
        link_names: the robot's links (no object may take a link's name).
        scene_file: where this instance keeps the scene (default
            :func:`arduinobot.service.scene.file.default_scene_file`).
        description: the robot (without it, attach and detach are refused).
        robot: computes link poses and contacts (default: a RobotFrames of description).
        meshes: parses inline meshes (the service's worker pool; default: here).
    """

    def __init__(self, session: zenoh.Session, prefix: str, instance: str,
                 link_names: tuple[str, ...], *, scene_file: str | os.PathLike[str] | None = None,
                 description: Description | None = None,
                 robot: Frames | None = None, meshes: MeshStore | None = None) -> None:
        self.session, self.prefix, self.instance = session, prefix, instance
        owner = None if description is None else scene_owner(
            description.robot.name, description.robot.source)
        path = scene_file if scene_file is not None else default_scene_file(prefix, owner)
        self.file = SceneFile(path, owner=owner)
        # the one file per prefix kept before scenes were per robot (whose, it cannot say)
        self._legacy = default_scene_file(prefix) if scene_file is None and owner else None
        # robot: who computes link poses and contacts (the service's: its worker pool)
        if robot is None and description is not None:
            from arduinobot.planner.frames import RobotFrames  # only a worker's frames
            robot = RobotFrames(description)
        self.builder = SceneBuilder(link_names, mesh_dir_for(path), robot=robot,
                                    meshes=meshes)
        self._lock = threading.Lock()  # held while the state changes (and is written)
        self._state = SceneState()
        # the scene before this one: a plan that took it may still read its mesh files
        self._previous = self._state
        self._encoded = EncodedScenes()  # each scene's reply and digest, encoded once
        # one thread applies (and forwards), another takes changes from the leader: a
        # follower forwarding an apply can still take the leader's sync of it
        self._writes = concurrent.futures.ThreadPoolExecutor(1, "scene-apply")
        self._syncs = concurrent.futures.ThreadPoolExecutor(1, "scene-sync")
        self._entities: list[Any] = []
        self._shared: list[Any] = []  # held until the session closes
        self._publisher: Any = None
        self.instances = Instances(session, prefix, instance, on_return=self._member_returned)
        self._started = False
        # why this instance's scene may be stale (None: current), and a count of the
        # reasons given, so a catch-up clears only what was known when it began
        self._behind: str | None = None
        self._behind_count = 0
        self._behind_lock = threading.Lock()
        # stopped (SIGSTOP, a VM pause) and not caught up since: it may not lead
        self._stalled = False
        self.election = Election(session, prefix, instance, self.instances,
                                 ready=lambda: not self._stalled, on_stall=self._was_stopped)
        # apply_id -> the revision it made (the leader's and every member's that took it)
        self._applied: OrderedDict[str, int] = OrderedDict()
        self._ids = itertools.count(1)
        self._turns = Turns()  # the leader's: who lost the last if_revision race

    @property
    def state(self) -> SceneState:
        """The scene now (a plan takes ``state.snapshot`` when it arrives)."""
        return self._state

    # -- lifecycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Load the file, take changes, catch up with the live instances, serve the keys."""
        self.file.clean()  # what a kill -9 mid-write left
        unreadable: InvalidRequest | None = None
        data: dict[str, Any] | None = None
        try:
            data = self.file.load()
        except InvalidRequest as e:
            unreadable = e
        if data is None and unreadable is None and self._legacy is not None \
                and self._legacy.is_file():
            _log.info("scene: none kept yet for this robot in %s; %s holds a scene kept "
                      "before scenes were per robot (`arduinobot scene load %s` takes it)",
                      self.file.path, self._legacy, self._legacy)
        if data is not None:
            foreign = foreign_owner(data, self.file.owner)
            if foreign is not None:
                # an explicit --scene-file of another robot: the user's choice, said loudly
                _log.warning("scene: %s holds another robot's kept scene: %s; its objects "
                             "are loaded as they are (give --scene-file to keep this "
                             "robot's scene elsewhere)", self.file.path, foreign)
            try:
                self._state = self._previous = restore(data, self.builder)
                _log.info("scene: revision %d, %d objects from %s", self._state.revision,
                          len(self._state.objects), self.file.path)
            except InvalidRequest as e:
                unreadable = e
        self._collect()  # what a killed instance left: meshes of refused or old scenes
        p, me = self.prefix, f"{self.prefix}/instance/{self.instance}"
        liveliness = self.session.liveliness()
        self._entities += self.instances.subscribe()
        # takes changes from now on (the leader sends them to every member), then asks
        # for the scene: no change falls between the two
        self._declare(f"{me}/scene/sync", self._on_sync, complete=False, exact=True)
        self._entities.append(liveliness.declare_token(f"{p}/scene/member/{self.instance}"))
        # an unreadable file is set aside before a catch-up writes the live scene over it
        aside = self.file.set_aside() if unreadable is not None else None
        answered = self._catch_up()
        if unreadable is not None and aside is not None:
            self._start_without_the_file(unreadable, data, answered, aside)
        self._publisher = self.session.declare_publisher(f"{p}/scene/changes")
        self._declare(f"{p}/scene", self._on_get, shared=True)
        self._declare(f"{me}/scene", self._on_get)
        # changes only on their exact keys, as the work keys (see arduinobot.service.keyguard): a
        # wildcard query passes an ACL rule written for the key, and would fan out
        apply_ = self._queued(self._writes, self._apply_or_forward)
        self._declare(f"{p}/scene/apply", apply_, shared=True, exact=True)
        self._declare(f"{me}/scene/apply", apply_, exact=True)
        self._declare(f"{me}/scene/lead", self._queued(self._writes, self._lead), exact=True)
        # answered last: an instance leads only once it serves its scene
        self._declare(self.election.key(self.instance), self.election.answer, exact=True)
        self.election.start()
        self._started = True

    def _start_without_the_file(self, error: InvalidRequest, data: Mapping[str, Any] | None,
                                answered: int, aside: Path) -> None:
        """The kept file cannot be read (not JSON, an object no longer valid) and was set
        aside (as ``aside``): start from the live instances' scene, or, alone, put the file
        back and stop naming the file, the object and the field (a scene silently emptied
        would lose its objects).

        Raises:
            InvalidRequest: no live instance answered (``details``: ``file``, ``field``,
                ``object``).
        """
        where = object_named(data or {}, error.field)
        what = f"{where}: {error}" if where else str(error)
        if not answered:
            os.replace(aside, self.file.path)
            raise InvalidRequest(
                f"the kept scene file {self.file.path} cannot be read: {what}; no live "
                f"instance of '{self.prefix}' answered to start from. Fix or remove that "
                "in the file, move the file aside (an empty scene), or give --scene-file",
                details={"field": error.field, "file": str(self.file.path),
                         "object": where})
        with self._lock:
            self.file.save(self._state)
        _log.warning("scene: the kept scene file could not be read (%s); started from the "
                     "live instances' scene, revision %d, and set the file aside as %s",
                     what, self._state.revision, aside)

    # -- staying current -----------------------------------------------------------------
    def check_current(self) -> None:
        """Raises: SceneUnavailable (BUSY) while this instance catches up."""
        why = self._behind
        if why is not None:
            raise SceneUnavailable(f"this instance's kept scene is catching up ({why}); "
                                   "retry", details={"reason": "catching_up",
                                                     "retry_after": CATCH_UP_RETRY})

    def _fall_behind(self, why: str) -> None:
        """Mark the scene possibly stale and fetch the newest (on the sync thread)."""
        with self._behind_lock:
            self._behind = why
            self._behind_count += 1
        _log.info("scene: %s: fetching the newest scene of the live instances", why)
        self._schedule_catch_up()

    def _was_stopped(self, gap: float) -> None:
        with self._behind_lock:
            self._stalled = True
        self._fall_behind(f"this process was stopped for {gap:.1f} s")

    def _member_returned(self, inst: str) -> None:
        if self._started:  # at start, _catch_up does it
            self._fall_behind(f"instance {inst[:8]} is back after its token went")

    def _catch_up_again(self) -> None:
        with self._behind_lock:
            seen = self._behind_count
        try:
            self._catch_up()
        except Exception as e:  # a full disk, a bad scene: say it, stay behind, retry
            _log.error("scene: catching up failed (%s: %s): plans wait; retrying in %g s",
                       type(e).__name__, e, CATCH_UP_RETRY)
            timer = threading.Timer(CATCH_UP_RETRY, self._schedule_catch_up)
            timer.daemon = True
            timer.start()
            return
        with self._behind_lock:
            if self._behind_count == seen:  # nothing new fell behind meanwhile
                self._behind = None
                self._stalled = False
        _log.info("scene: current at revision %d", self._state.revision)

    def _schedule_catch_up(self) -> None:
        """A catch-up on the sync thread (none once this instance is closing)."""
        try:
            self._syncs.submit(self._catch_up_again)
        except RuntimeError:
            pass  # shut down: this instance is closing

    def close(self) -> None:
        self.election.close()
        self._writes.shutdown(wait=True, cancel_futures=True)
        self._syncs.shutdown(wait=True, cancel_futures=True)
        for e in reversed(self._entities):
            try:
                e.undeclare()
            except zenoh.ZError:
                pass  # already gone with the session
        self._entities.clear()
        if self._publisher is not None:
            try:
                self._publisher.undeclare()
            except zenoh.ZError:
                pass
            self._publisher = None

    def _declare(self, key: str, handler: Callable[[zenoh.Query], None], *,
                 complete: bool = True, shared: bool = False, exact: bool = False) -> None:
        """A queryable on ``key``; a ``shared`` one (on a key every instance declares) is
        never undeclared, only closed with the session: see PlannerService.close; an
        ``exact`` one answers only queries naming ``key`` itself (arduinobot.service.keyguard)."""
        on_query = guarded(key, handler, exact=exact,
                           internal="unexpected failure in the scene")
        q = self.session.declare_queryable(key, on_query, complete=complete)
        (self._shared if shared else self._entities).append(q)

    def _queued(self, pool: concurrent.futures.Executor,
                work: Callable[[zenoh.Query, bytes, float], None]
                ) -> Callable[[zenoh.Query], None]:
        """A handler that hands the query to ``pool`` (never decoding or applying on
        Zenoh's callback thread, which every queryable shares), with its arrival time
        (wall clock [s])."""
        def handler(query: zenoh.Query) -> None:
            arrived = time.time()
            zb = query.payload
            if zb is not None and len(zb) > MAX_APPLY_PAYLOAD:
                reply_error(query, Code.INVALID_REQUEST, f"payload of {len(zb)} bytes "
                            f"exceeds the {MAX_APPLY_PAYLOAD}-byte cap",
                            {"limit": MAX_APPLY_PAYLOAD})
                return
            raw = zb.to_bytes() if zb is not None else b""

            def run() -> None:
                # a bug: INTERNAL naming the exception, the service lives
                with answering(query, f"scene: {query.key_expr}"):
                    work(query, raw, arrived)
                query.drop()
            try:
                pool.submit(run)
            except RuntimeError:  # shut down: this instance is closing
                reply_error(query, Code.SHUTTING_DOWN, "this instance is shutting down; "
                            "retry")
        return handler

    # -- reading -----------------------------------------------------------------------
    def encoded(self) -> bytes:
        """The scene's JSON with its digest (:mod:`.identity`), encoded once."""
        return self._encoded.of(self._state)[0]

    def _on_get(self, query: zenoh.Query) -> None:
        query.reply(query.key_expr, self.encoded(), encoding=wire.JSON)

    # -- writing -----------------------------------------------------------------------
    def leader(self) -> str:
        """The live instance with the smallest id that answers it is ready (this one
        counts, live or not yet): :meth:`Election.leader`."""
        return self.election.leader()

    def _apply_or_forward(self, query: zenoh.Query, raw: bytes, arrived: float) -> None:
        change = decode_apply(raw)  # refused here, at once, wherever the leader is
        if "apply_id" not in change:  # one id however often it is sent on
            change = {**change, "apply_id": f"{self.instance[:12]}-{next(self._ids)}"}
            raw = orjson.dumps(change)
        source = None
        if change.get("attach") or change.get("detach") or any(
                o.get("shape") == "points" and "state" not in o
                for o in change.get("add") or ()):
            # the state here, once: the leader and every follower replay this one (a
            # cloud is self-filtered at the state it was taken)
            change, source = with_robot_state(change, session=self.session,
                                              prefix=self.prefix, robot=self.builder.robot)
            raw = orjson.dumps(change)
        give_up = time.monotonic() + LEADER_WAIT
        while True:
            lead = self.leader()
            _log.debug("scene: apply, leader %s", lead[:8])
            if lead == self.instance:
                return self._lead_change(query, change, source, arrived=arrived)
            replies = list(self.session.get(f"{self.prefix}/instance/{lead}/scene/lead",
                                            payload=raw, timeout=FORWARD_TIMEOUT,
                                            encoding=wire.JSON))
            if replies:
                r = replies[0]
                other = _not_leader(r.err.payload.to_bytes()) if r.err is not None else None
                if other is not None and time.monotonic() < give_up:
                    # it chose another (which this instance passed over): ask that again
                    _log.info("scene: %s does not lead, %s does: asking again", lead, other)
                    self.election.reconsider(other)
                    time.sleep(0.05)
                    continue
                if r.ok is not None:
                    body = r.ok.payload.to_bytes()
                    if source is not None:
                        body = orjson.dumps({**orjson.loads(body), "state_source": source})
                    query.reply(query.key_expr, body, encoding=wire.JSON)
                elif r.err is not None:
                    query.reply_err(r.err.payload.to_bytes(), encoding=wire.JSON)
                return None
            if time.monotonic() > give_up:
                raise SceneUnavailable("the scene's leading instance did not answer; retry")
            # it has just gone: its liveliness token goes too, and the next one leads
            _log.warning("scene: leader %s did not answer an apply; asking again", lead)
            time.sleep(0.2)

    def _lead(self, query: zenoh.Query, raw: bytes, arrived: float) -> None:
        lead = self.leader()
        if lead != self.instance:  # two views for a moment: one writer all the same
            raise SceneUnavailable(f"instance {self.instance} does not lead the scene, "
                                   f"{lead} does; retry",
                                   details={"reason": "not_leader", "leader": lead})
        self._lead_change(query, decode_apply(raw), arrived=arrived)

    def _collect(self) -> None:
        """Remove the mesh files neither this scene nor the one before it uses (the
        caller holds the lock, or nothing else runs yet)."""
        collect_meshes(self.builder.mesh_dir, (self._state, self._previous))

    def _install(self, new: Callable[[], SceneState]) -> tuple[SceneState, SceneState]:
        """The scene ``new()`` builds (on disk before anyone hears of it) made this
        instance's, under the lock; the scene before and after. The mesh files it wrote
        are collected if it fails (a refused apply leaves none), and those no scene uses
        any more if it does."""
        with self._lock:
            before = self._state
            try:
                state = new()
                if state is not before:
                    self.file.save(state)
            except BaseException:
                self._collect()
                raise
            if state is not before:
                self._previous, self._state = before, state
            self._collect()
            return before, state

    def _remember(self, apply_id: object, revision: int) -> None:
        if isinstance(apply_id, str):
            self._applied[apply_id] = revision
            self._applied.move_to_end(apply_id)
            while len(self._applied) > REMEMBERED_APPLIES:
                self._applied.popitem(last=False)

    def _lead_change(self, query: zenoh.Query, change: Mapping[str, Any],
                     source: StateSource | None = None, *, arrived: float) -> None:
        if not self.election.ready():  # stopped: what it holds may be old
            raise SceneUnavailable(f"instance {self.instance} was stopped and is catching "
                                   "up before it leads; retry",
                                   details={"reason": "catching_up",
                                            "retry_after": CATCH_UP_RETRY})
        done = self._applied.get(str(change.get("apply_id")))
        if done is not None:
            now = self._state
            _log.info("scene: apply %s was applied at revision %d: answered again, "
                      "nothing changed", change.get("apply_id"), done)
            query.reply(query.key_expr, orjson.dumps({
                "revision": done, "objects": len(now.objects) + len(now.clouds),
                "attached": len(now.attached), "already_applied": True,
                "leader": self.instance}),
                encoding=wire.JSON)
            return
        old, new = self._install_fairly(change)
        if new is not old:
            self._remember(change.get("apply_id"), new.revision)
        missed = self._replicate(old, new.revision, change)
        added = [o.id for o in new.objects if o.id not in set(old.ids())]
        removed = [i for i in old.ids() if i not in set(new.ids())]
        attached = [i for i in new.attached_ids() if i not in set(old.attached_ids())]
        detached = [i for i in old.attached_ids() if i not in set(new.attached_ids())]
        self._publisher.put(orjson.dumps({"revision": new.revision, "added": added,
                                          "removed": removed, "attached": attached,
                                          "detached": detached,
                                          "cleared": bool(change.get("clear")),
                                          "arrived": arrived}),
                            encoding=wire.JSON)
        reply: dict[str, Any] = {"revision": new.revision,
                                 "objects": len(new.objects) + len(new.clouds),
                                 "attached": len(new.attached), "leader": self.instance}
        if source is not None:
            reply["state_source"] = source
        if missed:
            reply["not_taken_by"] = missed
        taken = {o.get("id") for o in change.get("add") or () if o.get("shape") == "points"}
        if taken:  # what became of each cloud's points
            reply["clouds"] = {c.id: dict(c.counts) for c in new.clouds if c.id in taken}
        query.reply(query.key_expr, orjson.dumps(reply), encoding=wire.JSON)

    def _install_fairly(self, change: Mapping[str, Any]) -> tuple[SceneState, SceneState]:
        """:meth:`_install` of ``change``, the writer that lost the last ``if_revision``
        race first (:mod:`arduinobot.service.scene.turns`).

        Raises:
            SceneConflict: a stale ``if_revision`` (``details.turn`` and
                ``retry_within`` when this writer asked for turns and gets the next,
                ``retry_after`` while another holds it), or another writer's turn
                (``reason: turn_held``).
        """
        now = self._state.revision
        wait = self._turns.blocks(change, now)
        if wait is not None:
            raise SceneConflict(f"another writer holds the turn at revision {now} (it lost "
                                f"the last race); retry in {wait:.2f} s",
                                field="if_revision", current_revision=now,
                                details={"reason": "turn_held", "retry_after": round(wait, 3)})
        try:
            return self._install(lambda: apply(self._state, change, self.builder))
        except SceneConflict as e:
            if e.field != "if_revision":
                raise
            turn = self._turns.lost(change, e.current_revision)
            if turn is None:
                held = self._turns.held(e.current_revision)
                if held is None:
                    raise
                left = max(held.until - time.monotonic(), 0.0)
                raise SceneConflict(
                    f"the scene is at revision {e.current_revision}, not "
                    f"{change['if_revision']}, and another writer holds the next turn: read "
                    f"it and apply again in {left:.2f} s", field="if_revision",
                    current_revision=e.current_revision,
                    details={"reason": "stale", "retry_after": round(left, 3)}) from None
            raise SceneConflict(
                f"the scene is at revision {e.current_revision}, not {change['if_revision']}: "
                f"read it and apply again with turn '{turn.token}' within {TURN_TIME:g} s "
                "(the next conditional apply at that revision is yours)", field="if_revision",
                current_revision=e.current_revision,
                details={"reason": "stale", "turn": turn.token,
                         "retry_within": TURN_TIME}) from None

    def _replicate(self, base: SceneState, revision: int, change: Mapping[str, Any]
                   ) -> list[str]:
        """Have every other live instance take the change to ``base`` (answered once it
        is on their disk too), before the apply is acknowledged; the members that did
        not."""
        payload = orjson.dumps({"from": self.instance, "base": base.revision,
                                "base_digest": self._encoded.digest(base),
                                "revision": revision, "change": change})
        members = sorted(self.instances.members())
        # one exact query per member, all sent before any answer is awaited
        pending = [(m, self.session.get(f"{self.prefix}/instance/{m}/scene/sync",
                                        payload=payload, timeout=REPLICATE_TIMEOUT,
                                        encoding=wire.JSON)) for m in members]
        missed = []
        for member, replies in pending:
            got = list(replies)
            if not got or got[0].err is not None:
                why = got[0].err.payload.to_bytes()[:300] if got and got[0].err else "no reply"
                _log.warning("scene: instance %s did not take revision %d (%s): it "
                             "catches up before it plans again", member, revision, why)
                missed.append(member)
        return missed

    def _on_sync(self, query: zenoh.Query) -> None:
        raw = query.payload.to_bytes() if query.payload is not None else b""
        self._queued(self._syncs, self._take)(query) if raw else query.drop()

    def _take(self, query: zenoh.Query, raw: bytes, arrived: float) -> None:
        msg = orjson.loads(raw)
        sender = str(msg["from"])
        if sender != self.instance:
            def taken() -> SceneState:
                state = self._state
                theirs = msg.get("base_digest")
                if state.revision == msg["base"] and theirs is not None \
                        and theirs != self._encoded.digest(state):
                    _log.warning("scene: revision %d here is not %s's revision %d (another "
                                 "scene made apart: a partition or a pause): taking its "
                                 "scene", state.revision, sender, msg["base"])
                    return self._fetch(sender) or state
                if state.revision == msg["base"]:
                    took = apply(state, msg["change"], self.builder)
                    self._remember(msg["change"].get("apply_id"), took.revision)
                    return took
                if state.revision < msg["revision"]:  # missed some: take it all
                    _log.info("scene: at revision %d, %s sent %d -> %d: fetching its scene",
                              state.revision, sender, msg["base"], msg["revision"])
                    return self._fetch(sender) or state
                _log.warning("scene: at revision %d, %s sent %d -> %d: ignored",
                             state.revision, sender, msg["base"], msg["revision"])
                return state
            try:
                self._install(taken)
            except Exception as e:  # not kept (a full disk): the leader hears it too
                self._fall_behind(f"revision {msg['revision']} could not be kept: "
                                  f"{type(e).__name__}")
                raise
        query.reply(query.key_expr, orjson.dumps({"revision": self._state.revision}),
                    encoding=wire.JSON)

    def _fetch(self, instance: str) -> SceneState | None:
        """The scene of ``instance``, or None if it does not answer."""
        for reply in self.session.get(f"{self.prefix}/instance/{instance}/scene",
                                      timeout=CATCH_UP_TIMEOUT):
            if reply.ok is not None:
                return restore(orjson.loads(reply.ok.payload.to_bytes()), self.builder)
        return None

    def _catch_up(self) -> int:
        """Take the newest scene among the live instances' if it is newer than the file's;
        how many instances answered. Every instance with a liveliness token is asked until
        it answers (its queryables may reach this new session a moment after the session
        opens), for at most :data:`CATCH_UP_TIMEOUT`."""
        deadline = time.monotonic() + CATCH_UP_TIMEOUT
        scenes = self._scenes("*")
        missing = self.instances.live() - set(scenes) - {self.instance}
        while missing and time.monotonic() < deadline:
            time.sleep(0.1)
            for inst in sorted(missing):
                scenes.update(self._scenes(inst))
            missing = self.instances.live() - set(scenes) - {self.instance}
        if missing:
            _log.warning("scene: instances %s did not answer; starting from the newest "
                         "scene of the others and the file", ", ".join(sorted(missing)))
        mine = self._state
        best = max(scenes.values(), key=lambda d: d.get("revision", -1), default=None)
        lead = scenes.get(self.leader()) if self.leader() != self.instance else None
        if lead is not None and lead.get("revision") == mine.revision \
                and lead.get("digest") not in (None, self._encoded.digest(mine)):
            # the same number, another scene (made apart): the leader's is the scene
            _log.warning("scene: revision %d here is not the leader's revision %d (another "
                         "scene made apart: a partition or a pause): taking the leader's",
                         mine.revision, mine.revision)
            best = lead
        elif best is None or best.get("revision", -1) <= mine.revision:
            return len(scenes)
        # restored under the lock (its mesh files are written where a sync collects),
        # unless a change came in meanwhile
        _, new = self._install(lambda: restore(best, self.builder)
                               if self._state is mine else self._state)
        _log.info("scene: caught up to revision %d from the live instances", new.revision)
        return len(scenes)

    def _scenes(self, instance: str) -> dict[str, dict[str, Any]]:
        """The scenes of the instances ``instance`` matches (``*``: all), by id."""
        out = {}
        for reply in self.session.get(f"{self.prefix}/instance/{instance}/scene",
                                      target=zenoh.QueryTarget.ALL,
                                      consolidation=zenoh.ConsolidationMode.NONE,
                                      timeout=CATCH_UP_TIMEOUT):
            if reply.ok is not None:
                inst = str(reply.ok.key_expr).split("/instance/", 1)[1].split("/", 1)[0]
                out[inst] = orjson.loads(reply.ok.payload.to_bytes())
        return out



def _not_leader(err: bytes) -> str | None:
    """The leader another instance names when it refuses to lead (``not_leader``)."""
    try:
        details = orjson.loads(err)["error"]["details"]
    except (orjson.JSONDecodeError, KeyError, TypeError):
        return None
    if isinstance(details, dict) and details.get("reason") == "not_leader":
        leader = details.get("leader")
        return leader if isinstance(leader, str) else None
    return None
