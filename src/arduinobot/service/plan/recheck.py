"""A running motion's rest re-certified against the kept scene now (a ``recheck`` job).

The execute wing (:mod:`arduinobot.service.execute.react`) sends, when the kept scene
changes while the arm moves, the states the arm is still to be commanded through: the
trajectory's positions at every control tick from now to its end. The worker certifies
the polyline through them with the planner's own proof
(:class:`arduinobot.planner.collision.proof.certify.Certifier`, in the world a plan of
that request would have now: the kept scene's objects, clouds and carried objects, the
request's own obstacles and ground; a rest that lifts a carried object off what it
rests on, in the world the lift was planned in: :mod:`arduinobot.planner.planning.resting`).
A servo is commanded those states one tick apart;
between two of them it moves by a hundredth of a second's motion, which the straight
piece stands for.

When the whole rest is not certified, the answer says where the first refusal fell and
the longest prefix that *is* certified (its last state ``safe``): the proof walks pair by
pair, so a refusal at piece ``k`` of one pair does not prove pieces before ``k`` for the
pairs after it; the prefix up to the refused piece is certified again, until it passes
(or nothing is left). A stop along the path that comes to rest at or before state
``safe`` moves only through certified states.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from arduinobot.contract.errors import InvalidRequest

if TYPE_CHECKING:
    from arduinobot.description import Description
    from arduinobot.planner.collision.world import CollisionWorld
    from arduinobot.planner.kinematics.chain import Kinematics
    from arduinobot.scene.state import SceneSnapshot


class Handlers(Protocol):
    """What a recheck needs of the worker's handlers
    (:class:`arduinobot.service.plan.handlers.Handlers`): the robot, its kinematics, the
    world of a set of obstacles, and where the last recheck's certifier is kept."""

    description: Description
    kin: Kinematics
    recheck_certifier: tuple[Any, Any] | None

    def scene_world(self, obs: tuple[Any, ...], padding: float,
                    clouds: tuple[Any, ...] = (), *, ground: bool = True,
                    attached: tuple[Any, ...] = (),
                    allowed: tuple[tuple[str, str], ...] = ()) -> CollisionWorld: ...

_log = logging.getLogger(__name__)

#: prefixes certified again at most, after the first refusal (each one is shorter)
MAX_PREFIXES = 8


def certifier(handlers: Handlers, world: CollisionWorld) -> Any:
    """The certifier of ``world``: one per world (its one-joint cells and work buffers),
    kept while the planner keeps the world (its obstacle set in use)."""
    from arduinobot.planner.collision.proof.certify import Certifier
    held = handlers.recheck_certifier
    if held is not None and held[0] is world:
        return held[1]
    cert = Certifier(world)
    handlers.recheck_certifier = (world, cert)
    return cert


def certify_rest(cert: Any, full: np.ndarray) -> dict[str, Any]:
    """``{"certified"}`` of the polyline through ``full`` ((m, dof) [rad]) and, when not,
    ``"refused"`` (the first refused piece: its first state's index, the pair) and
    ``"safe"`` (the last state of the longest certified prefix; -1: none)."""
    got = cert.path(full)
    if got.free:
        return {"certified": True}
    assert got.failure is not None
    first = int(got.failure[0])
    out: dict[str, Any] = {"certified": False,
                           "refused": {"state": first, "pair": list(got.failure[2])}}
    end = first  # the prefix through state ``end`` (pieces 0 .. end-1)
    for _ in range(MAX_PREFIXES):
        if end < 1:
            end = -1
            break
        pre = cert.path(full[:end + 1])
        if pre.free:
            break
        assert pre.failure is not None
        end = min(end - 1, int(pre.failure[0]))
    else:
        end = -1  # never proven within the tries: nothing counts as certified
    out["safe"] = end
    return out


def _lifting(handlers: Handlers, world: CollisionWorld, obs: tuple[Any, ...],
             clouds: tuple[Any, ...], carried: tuple[Any, ...], full: np.ndarray, *,
             ground: bool) -> CollisionWorld:
    """``world``, or, when the rest starts with a carried object resting on something
    (a line lifting it off: :mod:`arduinobot.planner.planning.resting`) and ends with it
    clear, the world the lift was planned in: the pair allowed, the support's core
    checked against the object (never more than ``DEPTH`` into it)."""
    from arduinobot.planner.planning.resting import lifting_world
    chk = world.check(full[0])
    if chk.valid:
        return world
    found = lifting_world(world.kin, carried, world.obstacles, chk.pairs, full[0], full[-1])
    if found is None:
        return world
    cores, allowed = found
    return handlers.scene_world((*obs, *cores), 0.0, clouds, ground=ground,
                                attached=carried, allowed=allowed)


def full_states(handlers: Handlers, names: list[str], qs: np.ndarray,
                hold: Mapping[str, Any] | None) -> np.ndarray:
    """``qs`` ((m, len(names)) [rad]) in the kinematics' joint order, the joints not
    named at ``hold`` (else 0)."""
    order = handlers.kin.joint_names
    held = {str(k): float(v) for k, v in (hold or {}).items()}
    full = np.empty((len(qs), len(order)))
    for j, n in enumerate(order):
        full[:, j] = qs[:, names.index(n)] if n in names else held.get(n, 0.0)
    return full


def recheck(handlers: Handlers, data: Mapping[str, Any], *,
            scene: SceneSnapshot | None) -> dict[str, Any]:
    """Certify ``data["positions"]`` ((m, len(joint_names)) [rad], one control tick
    apart) against ``scene`` and the plan request's own ``obstacles``, ``ground`` and
    ``attached``; joints not named hold ``data["hold"]`` (else 0).

    Returns ``{"certified", "scene_revision", "states", "seconds"}`` and, when not
    certified, ``"refused"`` (the first refused piece: the index of its first state, and
    the pair) and ``"safe"`` (the last state of the longest certified prefix; -1: not
    even the first piece).
    """
    from arduinobot.scene.state import with_scene
    from arduinobot.service.plan.plan_io import attached
    from arduinobot.service.plan.requests import obstacles

    t0 = time.perf_counter()
    desc = handlers.description
    names = list(data.get("joint_names") or ())
    qs = np.asarray(data.get("positions") or (), float)
    if qs.ndim != 2 or qs.shape[1] != len(names) or len(qs) < 1:
        raise InvalidRequest(f"positions must be (m, {len(names)}) for joint_names "
                             f"{names}, not {qs.shape}", field="positions")
    full = full_states(handlers, names, qs, data.get("hold"))
    obs, revision = with_scene(scene, {}, obstacles(desc, data.get("obstacles")))
    carried = attached(desc, data.get("attached"), scene=scene, obstacles=obs)
    clouds = scene.clouds if scene is not None else ()
    ground = bool(data.get("ground", True))
    world = handlers.scene_world(obs, 0.0, clouds, ground=ground)
    if carried:
        world = world.with_scene(world.obstacles, attached=carried)
        world = _lifting(handlers, world, obs, clouds, carried, full, ground=ground)
    out: dict[str, Any] = {"scene_revision": revision, "states": len(full),
                           **certify_rest(certifier(handlers, world), full)}
    out["seconds"] = time.perf_counter() - t0
    _log.info("recheck at scene revision %d: %d states %s in %.3f s", revision, len(full),
              "certified" if out["certified"] else
              f"refused at state {out['refused']['state']} ({out['refused']['pair']}), "
              f"certified through {out['safe']}", out["seconds"])
    return out
