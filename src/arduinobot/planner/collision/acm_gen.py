"""Computing the allowed-collision matrix as MoveIt's setup assistant does, made sound.

Pairs are disabled as ``Adjacent`` (joined by a joint, possibly through links without
geometry, or rigidly by fixed joints), ``Always`` (colliding in every one of N seeded
samples), or ``Never-proven``: the setup assistant calls a pair "never" when it did not
touch in N samples, which a narrow corner of the joint space can prove wrong; here a
pair is skipped only when :mod:`arduinobot.planner.collision.acm_proof` proves it apart everywhere within the
joint limits. Pairs that merely never touched in the samples can be recorded as
``Never-sampled`` for MoveIt (which skips them); this project keeps checking them.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from arduinobot.description import Description
from arduinobot.description.srdf import DisabledCollision
from arduinobot.planner.collision.acm import AllowedCollisionMatrix, adjacent_pairs
from arduinobot.planner.collision.acm_proof import prove_never
from arduinobot.planner.collision.world import CollisionWorld

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class AcmReport:
    """The computed pairs and how they were found.

    Attributes:
        disabled: the pairs to write into the SRDF, with reasons.
        unproven: pairs that never collided in the samples but that the bound could not
            prove apart; they stay checked.
        collision_counts: (link1, link2) -> samples in collision.
        samples: how many random states were checked.
        seconds: wall time [s].
    """

    disabled: tuple[DisabledCollision, ...]
    unproven: tuple[tuple[str, str], ...]
    collision_counts: dict[tuple[str, str], int]
    samples: int
    seconds: float


def compute_acm(description: Description, *, samples: int = 10000, seed: int = 0,
                budget: int = 3000, margin: float = 0.001, always_fraction: float = 1.0,
                include_sampled: bool = False) -> AcmReport:
    """Recompute the disabled pairs of ``description``'s links.

    Args:
        samples: random states (uniform within the limits) to check every pair in.
        seed: seeds the sampler.
        budget: distance bounds per pair the never-collide proof may spend.
        margin: distance [m] the proof must show.
        always_fraction: a pair colliding in at least this share of samples is
            ``Always``.
        include_sampled: also disable pairs that never touched in the samples but could
            not be proven apart, as ``Never-sampled`` (for MoveIt; never skipped here).
    """
    t0 = time.perf_counter()
    probe = CollisionWorld(description, acm=AllowedCollisionMatrix())
    bodies = probe.link_bodies
    adjacent = adjacent_pairs(description.robot, bodies)
    # adjacent pairs touch by construction: sampling them only costs narrow-phase calls
    world = CollisionWorld(description, acm=AllowedCollisionMatrix.from_pairs(
        tuple((min(p), max(p)) for p in adjacent), reason="Adjacent"))
    lim = description.robot.position_limits(world.kin.joint_names)
    rng = np.random.default_rng(seed)
    qs = rng.uniform(lim[:, 0], lim[:, 1], size=(samples, world.kin.dof))
    counts = {(a, b): 0 for a, b in combinations(bodies, 2)}
    for q in qs:
        for p in world.check(q).pairs:
            key = p if p in counts else (p[1], p[0])
            counts[key] += 1
    proof = prove_never(world, seed=seed, budget=budget, margin=margin)
    proven = {frozenset(p) for p in proof.proven}
    disabled, unproven = [], []
    for (a, b), n in counts.items():
        if frozenset((a, b)) in adjacent:
            disabled.append(DisabledCollision(a, b, "Adjacent"))
        elif samples and n >= always_fraction * samples:
            disabled.append(DisabledCollision(a, b, "Always"))
        elif frozenset((a, b)) in proven:
            disabled.append(DisabledCollision(a, b, "Never-proven"))
        elif n == 0:
            unproven.append((a, b))
            if include_sampled:
                disabled.append(DisabledCollision(a, b, "Never-sampled"))
    secs = time.perf_counter() - t0
    _log.info("ACM: %d disabled, %d unproven, %d samples in %.2f s", len(disabled),
              len(unproven), samples, secs)
    return AcmReport(tuple(disabled), tuple(unproven), counts, samples, secs)
