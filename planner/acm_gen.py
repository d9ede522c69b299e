"""Computing the allowed-collision matrix as MoveIt's setup assistant does, made sound.

Pairs are disabled as ``Adjacent`` (joined by a joint, possibly through links without
geometry), ``Always`` (colliding in every one of N seeded samples), or ``Never``. The
setup assistant calls a pair "never" when it did not touch in N samples, which a
narrow corner of the joint space can still prove wrong. Here a pair is ``Never`` only if
a bound over the joint limits proves it: the two links' bounding spheres, placed on a
grid over the joints between them and grown by how far any grid gap can move them, stay
apart everywhere.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from description import Description
from description.srdf import DisabledCollision

from .acm import AllowedCollisionMatrix, adjacent_pairs
from .collision import CollisionWorld

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


def _chain(robot, link: str) -> list:  # type: ignore[no-untyped-def]
    return list(robot.link_path(link))


def _proven_apart(world: CollisionWorld, a: str, b: str, *, grid: int,
                  margin: float) -> bool:
    """True if links a and b cannot touch anywhere within the joint limits."""
    robot = world.description.robot
    kin = world.kin
    ca, cb = _chain(robot, a), _chain(robot, b)
    common = 0
    while common < min(len(ca), len(cb)) and ca[common].name == cb[common].name:
        common += 1
    between = ca[common:] + cb[common:]
    names = kin.joint_names
    movers = sorted({names.index(j.mimic.joint if j.mimic else j.name) for j in between
                     if j.movable and (j.mimic.joint if j.mimic else j.name) in names})
    lim = robot.position_limits(names)
    axes = [np.linspace(lim[j, 0], lim[j, 1], grid) if movers else [0.0] for j in movers]
    h = {j: (lim[j, 1] - lim[j, 0]) / (grid - 1) for j in movers}
    mesh = np.meshgrid(*axes, indexing="ij") if movers else []
    qs = np.zeros((int(np.prod([len(x) for x in axes])) if movers else 1, kin.dof))
    for k, j in enumerate(movers):
        qs[:, j] = mesh[k].ravel()
    ia, ib = world.body_names.index(a), world.body_names.index(b)
    t = world._forest
    centers, radii, errs = [], [], []
    for body, _link, chain in ((ia, a, ca[common:]), (ib, b, cb[common:])):
        c = t.center[t.root[body]]
        centers.append(c)
        radii.append(float(np.linalg.norm(t.half[t.root[body]])))
        # how far the sphere centre can move per radian of each joint in its chain:
        # at most its distance from the joint, bounded by the origins' lengths after it
        err = 0.0
        for k, j in enumerate(chain):
            if not j.movable:
                continue
            reach = sum(np.linalg.norm(x.origin.xyz) for x in chain[k + 1:]) + np.linalg.norm(c)
            src = j.mimic.joint if j.mimic else j.name
            mult = abs(j.mimic.multiplier) if j.mimic else 1.0
            err += mult * h.get(names.index(src), 0.0) / 2 * reach
        errs.append(err)
    poses = kin.link_poses_batch(qs)
    pa = poses[:, kin.link_index[a], :3, :3] @ centers[0] + poses[:, kin.link_index[a], :3, 3]
    pb = poses[:, kin.link_index[b], :3, :3] @ centers[1] + poses[:, kin.link_index[b], :3, 3]
    gap = np.linalg.norm(pa - pb, axis=1) - radii[0] - radii[1] - errs[0] - errs[1]
    return bool(gap.min() > margin)


def compute_acm(description: Description, *, samples: int = 10000, seed: int = 0,
                grid: int = 41, margin: float = 0.01,
                always_fraction: float = 1.0) -> AcmReport:
    """Recompute the disabled pairs of ``description``'s links.

    Args:
        samples: random states (uniform within the limits) to check every pair in.
        seed: seeds the sampler.
        grid: grid points per joint for the never-collide bound.
        margin: distance [m] the bound must prove.
        always_fraction: a pair colliding in at least this share of samples is
            ``Always``.
    """
    t0 = time.perf_counter()
    probe = CollisionWorld(description, acm=AllowedCollisionMatrix())
    bodies = probe.link_bodies
    adjacent = adjacent_pairs(description.robot, bodies)
    # adjacent pairs touch by construction: sampling them only costs narrow-phase calls
    world = CollisionWorld(description, acm=AllowedCollisionMatrix.from_pairs(
        tuple(tuple(sorted(p)) for p in adjacent), reason="Adjacent"))
    lim = description.robot.position_limits(world.kin.joint_names)
    rng = np.random.default_rng(seed)
    qs = rng.uniform(lim[:, 0], lim[:, 1], size=(samples, world.kin.dof))
    counts = {(a, b): 0 for a, b in combinations(bodies, 2)}
    for q in qs:
        for p in world.check(q).pairs:
            key = p if p in counts else (p[1], p[0])
            counts[key] += 1
    disabled, unproven = [], []
    for (a, b), n in counts.items():
        if frozenset((a, b)) in adjacent:
            disabled.append(DisabledCollision(a, b, "Adjacent"))
        elif samples and n >= always_fraction * samples:
            disabled.append(DisabledCollision(a, b, "Always"))
        elif n == 0:
            if _proven_apart(probe, a, b, grid=grid, margin=margin):
                disabled.append(DisabledCollision(a, b, "Never"))
            else:
                unproven.append((a, b))
    secs = time.perf_counter() - t0
    _log.info("ACM: %d disabled, %d unproven, %d samples in %.2f s", len(disabled),
              len(unproven), samples, secs)
    return AcmReport(tuple(disabled), tuple(unproven), counts, samples, secs)
