"""A running task's rest re-certified, each step's piece in its own world (a ``recheck``
job with ``pieces``).

The execute wing (:mod:`arduinobot.service.execute.task_react`) sends, when the kept
scene changes while a task moves, the states the arm is still to be commanded through,
cut by the task's steps (:mod:`arduinobot.service.task.pieces`): each piece's positions
at every control tick, the objects the task carries there (posed on their links), the
pairs allowed to touch there (an object resting on its support until the lift clears
it), and the task's obstacles the kept scene does not give (its own; those it moves,
whose kept-scene copy is left out: ``moved``). Each piece is certified in order with the
planner's proof (:func:`arduinobot.service.plan.recheck.certify_rest`) in the kept scene
now plus that step's own state; the first piece not certified ends the check, and the
answer names it (``piece``), its first refused state and the last state of its longest
certified prefix (``safe``, within the piece; -1: none of it, so the rest is certified
through the previous piece's end).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.obstacles import Obstacle, refuse_files
from arduinobot.service.plan.recheck import Handlers, certifier, certify_rest, full_states

if TYPE_CHECKING:
    from arduinobot.planner.collision.world import CollisionWorld
    from arduinobot.scene.state import SceneSnapshot

_log = logging.getLogger(__name__)


def piece_world(handlers: Handlers, piece: Mapping[str, Any], *,
                scene: SceneSnapshot | None, moved: frozenset[str], ground: bool,
                where: str) -> CollisionWorld:
    """The world of one task piece: the kept ``scene``'s obstacles, clouds and carried
    objects but those the task moves (``moved``) or gives itself, the piece's obstacles,
    its carried objects and its allowed pairs."""
    from arduinobot.service.plan.plan_io import attached
    # from the wire (the execute request): no shape may name a file of this machine
    own = tuple(Obstacle.from_mapping(o, where=f"{where}.obstacles[{i}]", files=False)
                for i, o in enumerate(piece.get("obstacles") or ()))
    for i, a in enumerate(piece.get("attached") or ()):
        if isinstance(a, Mapping) and isinstance(a.get("object"), Mapping):
            refuse_files(a["object"], where=f"{where}.attached[{i}].object")
    given = {o.id for o in own}
    kept = scene.obstacles if scene is not None else ()
    obs = tuple(o for o in kept if o.id not in moved and o.id not in given) + own
    carried = attached(handlers.description, piece.get("attached"), scene=scene,
                       obstacles=obs)
    allowed = tuple((str(a), str(b)) for a, b in piece.get("allowed") or ())
    clouds = scene.clouds if scene is not None else ()
    return handlers.scene_world(obs, 0.0, clouds, ground=ground, attached=carried,
                                allowed=allowed)


def recheck_task(handlers: Handlers, data: Mapping[str, Any], *,
                 scene: SceneSnapshot | None) -> dict[str, Any]:
    """Certify ``data["pieces"]`` in order (see the module doc); joints not in
    ``joint_names`` hold ``data["hold"]`` (else 0).

    Returns ``{"certified", "scene_revision", "states", "seconds"}`` and, when not
    certified, ``"piece"`` (the index into ``pieces``), ``"refused"`` (the piece's first
    refused state and the pair) and ``"safe"`` (within that piece).
    """
    t0 = time.perf_counter()
    names = list(data.get("joint_names") or ())
    pieces = list(data.get("pieces") or ())
    moved = frozenset(str(m) for m in data.get("moved") or ())
    ground = bool(data.get("ground", True))
    revision = scene.revision if scene is not None else 0
    out: dict[str, Any] = {"scene_revision": revision, "certified": True}
    states = 0
    for k, piece in enumerate(pieces):
        where = f"pieces[{k}]"
        qs = np.asarray(piece.get("positions") or (), float)
        if qs.ndim != 2 or qs.shape[1] != len(names) or len(qs) < 1:
            raise InvalidRequest(f"positions must be (m, {len(names)}) for joint_names "
                                 f"{names}, not {qs.shape}", field=f"{where}.positions")
        full = full_states(handlers, names, qs, data.get("hold"))
        world = piece_world(handlers, piece, scene=scene, moved=moved, ground=ground,
                            where=where)
        states += len(full)
        got = certify_rest(certifier(handlers, world), full)
        if not got["certified"]:
            out = {**out, **got, "piece": k}
            break
    out["states"] = states
    out["seconds"] = time.perf_counter() - t0
    _log.info("task recheck at scene revision %d: %d states in %d pieces %s in %.3f s",
              revision, states, len(pieces),
              "certified" if out["certified"] else
              f"refused in piece {out['piece']} at state {out['refused']['state']} "
              f"({out['refused']['pair']})", out["seconds"])
    return out
