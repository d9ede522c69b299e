"""Proving link pairs can never collide anywhere within the joint limits.

With no SRDF, every pair but the joint-connected ones is checked, which is correct but
slow. A pair may be skipped only when a bound proves it apart in every configuration,
never because samples missed it. The proof is a branch and bound over the box of the
joints that move the two links relative to each other (their limits): at the centre
``c`` of a box with half widths ``h``, the OBB trees give a lower bound ``d`` on the
pair's distance, and no point of one link moves relative to the other by more than
``sum_k weight_k h_k`` anywhere in the box (:func:`arduinobot.planner.collision.proof.advance.pair_weights`). If
``d`` exceeds that by ``margin``, the whole box is proven; else it is split in two along
its most mobile joint, until an exact contact is found (the pair can touch) or the
budget runs out (unproven: the pair stays checked).

Sampling first (a seeded uniform sample of states) only decides which pairs are worth
a proof; a pair that touches in a sample is never skipped.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from arduinobot.planner.cache import ArtifactCache, content_key
from arduinobot.planner.collision.proof.advance import tree_lower_bound
from arduinobot.planner.collision.table import BodyKind
from arduinobot.planner.collision.world import CollisionWorld

_log = logging.getLogger(__name__)

# [m] distance bounds are capped here: farther pairs are simply "far"
_CAP = 10.0


@dataclass(frozen=True)
class NeverReport:
    """What the proof found for the world's checked link pairs.

    Attributes:
        proven: pairs apart everywhere within the joint limits (by the bound, or two
            links that never move and do not touch).
        touching: pairs found in contact at some state (a sample or a box centre).
        unproven: pairs the budget could not decide; they stay checked.
        evaluations: distance bounds computed.
        seconds: wall time [s].
    """

    proven: tuple[tuple[str, str], ...]
    touching: tuple[tuple[str, str], ...]
    unproven: tuple[tuple[str, str], ...]
    evaluations: int
    seconds: float


def prove_never(world: CollisionWorld, *, samples: int = 256, seed: int = 0,
                budget: int = 3000, margin: float = 1e-3) -> NeverReport:
    """Prove which of ``world``'s checked link pairs can never collide.

    Args:
        world: a robot-only world (obstacles are ignored); its allowed pairs are skipped.
        samples: seeded uniform states checked first; a pair touching in one is done.
        budget: distance bounds per pair before giving up on it.
        margin: clearance [m] the bound must prove beyond contact.
    """
    t0 = time.perf_counter()
    kin = world.kin
    table = world.table
    lim = world.description.robot.position_limits(kin.joint_names)
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi)
    rng = np.random.default_rng(seed)
    touching: set[tuple[str, str]] = set()
    for q in rng.uniform(lo, hi, size=(samples, kin.dof)):
        touching.update(world.check(q).pairs)
    proven: list[tuple[str, str]] = []
    unproven: list[tuple[str, str]] = []
    # two links that never move are decided at construction: apart or always touching
    for a, b in table.fixed:
        pair = (table.names[a], table.names[b])
        if table.kinds[a] == table.kinds[b] == BodyKind.LINK and pair not in table.fixed_hits:
            proven.append(pair)
    evaluations = 0
    f = world.forest
    frame = table.bodies.frame
    stack = np.empty((4096, 2), dtype=np.int64)
    gaps = np.empty(4096)
    scratch = np.empty((8, 3, 3))
    for p, (a, b) in enumerate(table.pairs.index):
        if table.pair_kinds(p) != (BodyKind.LINK, BodyKind.LINK):
            continue  # the matrix is the robot's: scene and carried bodies change
        pair = table.pair_names[p]
        if pair in touching or pair[::-1] in touching:
            continue
        weight = table.pairs.weight[p]
        moving = np.flatnonzero(weight > 1e-9)
        boxes = [((lo[moving] + hi[moving]) / 2, (hi[moving] - lo[moving]) / 2)]
        verdict = "proven"
        used = 0
        while boxes:
            if used >= budget:
                verdict = "unproven"
                break
            centre, half = boxes.pop()
            q = np.zeros(kin.dof)
            q[moving] = centre
            poses = kin.link_poses(q)
            d = tree_lower_bound(poses[frame[a]], f.root[a], poses[frame[b]], f.root[b],
                                 f.center, f.axes, f.half, f.left, f.right, 0.0, _CAP, stack,
                                 gaps, scratch)
            used += 1
            reach = weight[moving] * half
            if d - reach.sum() > margin:
                continue
            if d <= 0.0 and pair in world.check(q).pairs:
                verdict = "touching"
                break
            k = int(np.argmax(reach))
            for side in (-0.5, 0.5):
                c = centre.copy()
                c[k] += side * half[k]
                h = half.copy()
                h[k] /= 2
                boxes.append((c, h))
        evaluations += used
        {"proven": proven, "unproven": unproven}.get(verdict, []).append(pair)
        if verdict == "touching":
            touching.add(pair)
    secs = time.perf_counter() - t0
    _log.info("collision pairs: %d proven never to touch, %d touch, %d unproven (%d bounds, "
              "%.2f s)", len(proven), len(touching), len(unproven), evaluations, secs)
    return NeverReport(tuple(proven), tuple(sorted(touching)), tuple(unproven), evaluations,
                       secs)


# Bump when the proof changes: cached verdicts of an older proof are never read.
PROOF_VERSION = "1"


def proven_never_pairs(world: CollisionWorld, *, cache: ArtifactCache | None = None,
                       margin: float = 1e-3) -> tuple[tuple[str, str], ...]:
    """:func:`prove_never`'s proven pairs, from ``cache`` when the same robot geometry,
    kinematics, limits and allowed pairs were proven before (keyed by their content)."""
    desc = world.description
    key = content_key([
        PROOF_VERSION, desc.robot.urdf, repr(margin),
        repr(sorted(tuple(sorted((e.link1, e.link2))) for e in world.acm)),
        *(x for name, pts in world.bodies.points for x in (str(name), pts))])
    if cache is not None:
        hit = cache.load("never-pairs", key)
        if hit is not None:
            pairs = tuple((str(a), str(b)) for a, b in hit["pairs"].reshape(-1, 2))
            _log.info("collision pairs proven never to touch: %d (cached)", len(pairs))
            return pairs
    report = prove_never(world, margin=margin)
    if cache is not None:
        cache.store("never-pairs", key,
                    {"pairs": np.array(report.proven, dtype=str).reshape(-1, 2)})
    return report.proven
