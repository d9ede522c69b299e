"""A motion's certificate: whether it is proven free of collision, and its certified
clearance (:class:`Certificate`, made by :class:`.certify.Certifier`), how often each
rung of the near-contact ladder was used for it (:class:`Rungs`, :mod:`.ladder`), and one
for a motion made of certified ones (:func:`combine`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields


@dataclass(frozen=True)
class Rungs:
    """How often each rung of the certifier's near-contact ladder (:mod:`.ladder`) was
    used for a motion: queries made, cheapest rung first.

    Attributes:
        trees: OBB-tree bounds the walk evaluated.
        warm: hull bounds along a pair's last GJK direction, in the walk.
        hulls: convex-hull (GJK) queries.
        parts: part-hull queries (pairs with parts only).
        exact: FCL exact distance queries (``Certificate.exact`` counts those at the
            walk's stops; these include a still pair's, when not remembered).
        still: pairs proven before the walk by their bound at the start (with a
            clearance to report, pairs the motion barely moves).
        one_dim: pairs proven before the walk over cells of their one joint.
    """

    trees: int = 0
    warm: int = 0
    hulls: int = 0
    parts: int = 0
    exact: int = 0
    still: int = 0
    one_dim: int = 0

    def __add__(self, other: Rungs) -> Rungs:
        return Rungs(*(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)))


@dataclass(frozen=True)
class Certificate:
    """The outcome of certifying a motion.

    Attributes:
        free: every point of the motion is farther than ``clearance`` (plus ``GAP / 2``)
            from contact for every checked pair.
        clearance: the clearance [m] that was required.
        certified_clearance: a lower bound [m] on the distance over the whole motion and
            every checked pair (``>= clearance`` when free; half the tightest bound at
            worst, exact at the closest points FCL measured, and with a clearance to
            report (``fraction`` > 0) a pair the motion barely moves, such as the fingers
            in an arm motion, at its distance at the start less that motion).
        closest: the pair that bound belongs to.
        failure: when not free, (piece index, sigma [rad], pair, distance [m]) where the
            proof failed (a contact, a point closer than the clearance, or a query
            budget spent: distance NaN).
        bounds: OBB-tree distance bounds evaluated; ``exact``: FCL distance queries made
            (where the hulls could not prove the pair apart).
        rungs: how often each rung of the near-contact ladder was used.
    """

    free: bool
    clearance: float
    certified_clearance: float
    closest: tuple[str, str] | None
    failure: tuple[int, float, tuple[str, str], float] | None
    bounds: int
    exact: int
    rungs: Rungs = Rungs()


def combine(certificates: Sequence[Certificate]) -> Certificate:
    """One certificate for a motion made of the certified ones (the union of their
    motions): free if all are, the smallest certified clearance, the first failure."""
    if not certificates:
        raise ValueError("combine needs at least one certificate")
    worst = min(certificates, key=lambda c: c.certified_clearance)
    failed = next((c for c in certificates if not c.free), None)
    return Certificate(failed is None, certificates[0].clearance,
                       worst.certified_clearance if failed is None else failed.certified_clearance,
                       worst.closest if failed is None else failed.closest,
                       None if failed is None else failed.failure,
                       sum(c.bounds for c in certificates), sum(c.exact for c in certificates),
                       sum((c.rungs for c in certificates), Rungs()))
