"""The certifier's near-contact ladder: which bound proves a pair at a point.

A pair is proven by distance lower bounds, and the bounds come from rungs that cost more
the higher they stand and prove more near contact:

1. **trees**: the OBB trees (:mod:`.obbtree`, in the compiled walk). Far from contact
   they prove long steps for the cost of a shallow descent; the leaf boxes of CAD meshes
   (long thin triangles) prove nothing tens of millimetres before the meshes touch.
2. **warm hulls**: the convex hulls along the pair's last GJK direction (in the walk,
   :func:`.hulls.warm_bound`): near contact the steps are short and the hulls barely turn.
3. **hulls**: a new GJK query on the convex hulls (:mod:`.hulls`, ~20 us, Python).
4. **parts**: the part hulls (:mod:`.parts`, tens of us): a concave link near its
   hollows, where its convex hull holds the other body and proves nothing.
5. **exact**: FCL's exact distance (0.3-4 ms on CAD links), the reference, asked only
   where the rungs below prove (nearly) nothing.

Two kinds of pair are proven before the walk, without it: **still** pairs (a clearance to
report, a pair the motion barely moves: its bound at the start less that motion) and
**one-dim** pairs (the mimic fingers, over cells of their joint: :mod:`.one_dim`).

The walk climbs rungs 1-2 itself (where, is set by :data:`SOFT` and :data:`HOLD`) and
stops where it needs more; :class:`Ladder` then picks rungs 3-5 for that pair at that
point, remembering per pair what it learnt (the walk reads it: :attr:`Ladder.exact_below`,
:attr:`Ladder.ask`). :class:`Rungs` counts how often each rung is used for one motion
(:attr:`.certificate.Certificate.rungs`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from arduinobot.planner.collision.proof.certificate import Rungs
from arduinobot.planner.collision.proof.resume import Proof

if TYPE_CHECKING:
    from arduinobot.planner.collision.world import CollisionWorld

# [m] the proof shows every point at least this much beyond the clearance: a step is then
# never shorter than GAP / 2 / speed, so the walk ends (a graze closer than this to the
# clearance is refused, as a contact). Microns: below any servo's accuracy, far above
# rounding.
GAP = 1e-5
# [m] a pair whose trees prove less than this beyond the clearance gets a hull query too:
# the trees of CAD meshes are loose there, and a walk that took their small positive
# bounds stepped geometrically toward the leaf boxes' contact (thousands of bounds, and a
# clearance certified in microns for paths that kept centimetres). A couple of
# millimetres: well before the trees' bounds fall to microns, and near enough that a
# pair the trees keep apart never pays for a hull query.
SOFT = 0.002
# a warm hull bound under this fraction of the pair's last queried one is checked against
# the trees, and queried again: its direction may have gone stale as the bodies turned,
# and a stale direction leads the steps down geometrically as it turns away. A quarter:
# a bound shrinking as the walk closes in keeps its direction well above that.
HOLD = 0.25
# [m] where neither the trees nor the hulls prove a pair more than this beyond the
# clearance, the part hulls, else FCL's exact distance, are asked once per pair and
# motion: near a concave body (the claw over the base's hollow) the hulls' bound shrinks
# geometrically as the walk nears the hulls' contact while the meshes stay centimetres
# apart. A millimetre: 2 mm asked more exact queries for the same verdicts (docs/bench.md).
EXACT_BELOW = 0.001
# a pair whose exact (or part hulls') distance there exceeds LOOSE times the hulls' is
# asked again wherever the hulls prove less than EXACT_BELOW; else its hulls are tight
# there and go on alone. Twice: a hull bound within a factor of two of the distance
# still gives steps of the same order.
LOOSE = 2.0
# [m] there the part hulls are asked first, and FCL's exact distance only where they
# prove less than this beyond the clearance: microns, a true near contact (the part hulls
# are within a few percent of the exact distance at millimetres, so only a contact needs
# FCL; 0.1 mm gave the same figures, docs/bench.md).
PARTS_BELOW = 1e-5
# [m] where the hulls prove less than this beyond the clearance, the part hulls are asked
# too: closer, a concave link's hull may hold the other body in its hollow (the claw over
# the course base) and prove little; farther, a hull bound already proves long steps.
PARTS_ABOVE = 0.01
# [m] with a clearance to report, a pair the whole motion moves relative to itself by
# less than this is certified by its distance bound at the start less that motion
# (:func:`still_bound`): a tenth of a millimetre is below any clearance worth reporting
# and far above rounding.
STILL = 1e-4
# exact distance queries one certification may make before it gives up (refuses): a
# motion needing more is grazing along a contact, and a refusal lets the planner look
# elsewhere in bounded time.
MAX_EXACT = 4000
# hull and exact queries (walk stops) together: a hull query costs ~1/20 of an exact one.
MAX_NEAR = 40_000

# [m/rad] a joint moving a pair less than this per radian does not key its remembered
# still bound (pair_weights' rounding floor is 1e-12; any such joint's motion is
# subtracted)
_MOVES = 1e-9
# remembered still bounds per world before they are dropped
_STILL_KEPT = 1024


class Ladder:
    """The rungs above the walk for one certification (one motion) in one world, and
    what it learns per pair on the way (per motion, so a certificate never depends on
    what was certified before).

    Args:
        world: the collision world.
        clear: the clearance [m] required (the world's padding).
        max_exact: exact queries this certification may make before it is spent.
        max_near: walk stops (hull and exact queries) likewise.

    Attributes:
        exact_below: per pair [m]: the walk hands warm hull bounds under this (beyond the
            clearance) back for the part hulls or the exact distance (:data:`EXACT_BELOW`;
            0 once a pair's hulls proved tight there), shape (n_pairs,).
        ask: per pair: its last bound came from the part hulls, beating the trees and
            the hulls (the walk hands it back wherever its trees prove little).
        stops: walk stops handled; ``exact``: the exact queries among them.
    """

    def __init__(self, world: CollisionWorld, *, clear: float, max_exact: int = MAX_EXACT,
                 max_near: int = MAX_NEAR) -> None:
        n = len(world.table.pair_names)
        self.max_exact = max_exact
        self.max_near = max_near
        self.world = world
        self.clear = clear
        self.exact_below = np.full(n, EXACT_BELOW)
        self.ask = np.zeros(n, np.bool_)
        # the pair's exact (or parts') distance was compared with its hulls'
        self._tried = np.zeros(n, np.bool_)
        self._direction = np.empty(3)
        self.stops = 0
        self.exact = 0
        self._hulls = self._parts = self._exact = self._still = self._one_dim = 0

    def spent(self) -> bool:
        """Whether this certification's near-contact budgets are spent."""
        return self.exact >= self.max_exact or self.stops >= self.max_near

    def at_stop(self, q: np.ndarray, p: int, proven: float, proof: Proof) -> float:
        """A lower bound [m] on pair ``p``'s distance at state ``q`` where the walk
        stopped, ``proven`` what the walk's own bounds proved there (-1 for nothing).
        Keeps the pair's hull direction in ``proof`` for the walk's warm hulls."""
        direction, (_, directions, warm) = self._direction, proof
        direction[:] = np.nan
        if proven > self.clear + GAP:
            d, was_exact = self._past_the_trees(q, p, proven, proof)
        else:
            # free: the walk reached it from a checked sample, every point farther than
            # the clearance, so neither body can be inside the other; the hulls' bound
            # first (cheap), FCL's exact distance where the hulls touch
            d, was_exact = self.state_bound(q, p, above=self.clear + GAP,
                                            parts_below=self.clear + PARTS_ABOVE,
                                            direction=direction)
            if np.isfinite(direction[0]):
                directions[p] = direction
                warm[p] = True
            self.ask[p] = not was_exact
        self.exact += was_exact
        self.stops += 1
        return d

    def _past_the_trees(self, q: np.ndarray, p: int, proven: float,
                        proof: Proof) -> tuple[float, bool]:
        # the trees proved the pair free here, barely: the hulls' bound where it is better
        # (their direction kept for the walk), else the trees' again
        clear, direction, (_, directions, warm) = self.clear, self._direction, proof
        h = self._hull(q, p, direction)
        warm[p] = h > proven and bool(np.isfinite(direction[0]))
        if warm[p]:
            directions[p] = direction
        d, was_exact = max(h, proven), False
        self.ask[p] = False
        if not warm[p] or d <= clear + max(PARTS_ABOVE, self.exact_below[p]):
            # the part hulls' bound where the hulls do not help or may be loose (they
            # shrink geometrically as the walk nears their contact in a concave body's
            # hollow); else, reached without contact, the exact distance: both bounds
            e = self._part(q, p)
            self.ask[p] = e > d
            if d <= clear + self.exact_below[p]:
                if e <= clear + PARTS_BELOW:
                    e, was_exact = self._exact_distance(q, p), True
                if not self._tried[p]:
                    self._tried[p] = True
                    if not e > LOOSE * d:
                        self.exact_below[p] = 0.0  # tight hulls: alone from here on
            d = max(d, e)
        return d, was_exact

    def state_bound(self, q: np.ndarray, p: int, *, above: float,
                    parts_below: float | None = None,
                    direction: np.ndarray | None = None) -> tuple[float, bool]:
        """A lower bound [m] on pair ``p``'s distance at a state ``q`` reached without
        contact, climbing the rungs: the hulls' when that is above ``above`` and
        ``parts_below`` (default: ``above``), else the better of it and the part hulls'
        when that is above ``above``, else FCL's exact distance. The flag says which
        (True: exact). ``direction``: as for :meth:`.HullBounds.bound` (the hulls')."""
        d = self._hull(q, p, direction)
        if d > max(above, above if parts_below is None else parts_below):
            return d, False
        d = max(d, self._part(q, p))
        if d > above:
            return d, False
        return self._exact_distance(q, p), True

    def still_bound(self, q: np.ndarray, p: int, *, above: float) -> float:
        """A lower bound [m] on pair ``p``'s distance at a free state ``q``:
        :meth:`state_bound`'s with ``above`` where the joints that move the pair relative
        to itself (weight above ``_MOVES`` [m/rad]) are as in ``q`` and the others 0, less
        how far those others' values in ``q`` can move it. Remembered by the world, by
        the moving joints' values, so a pair no joint of a motion moves (the fingers in
        an arm motion) is measured once, and the same whatever was asked before (the
        others only ever add their rounding floor)."""
        w = self.world
        q = np.asarray(q, float)
        weight = w.table.pairs.weight[p]
        at = np.where(weight > _MOVES, q, 0.0)
        key = (p, above, at.tobytes())
        d = w.remembered.get(key)
        if d is None:
            if len(w.remembered) >= _STILL_KEPT:
                w.remembered.clear()
            d = w.remembered[key] = self.state_bound(at, p, above=above)[0]
        return d - float(weight @ np.abs(q - at))

    def proven_before(self, *, still: int, one_dim: int) -> None:
        """Count the pairs proven before the walk: ``still`` ones, ``one_dim`` ones."""
        self._still += still
        self._one_dim += one_dim

    def rungs(self, walk: np.ndarray) -> Rungs:
        """How often each rung was used so far, the walk's from its record ``walk``."""
        r = walk[0]
        return Rungs(trees=int(r["trees"]), warm=int(r["warm"]), hulls=self._hulls,
                     parts=self._parts, exact=self._exact, still=self._still,
                     one_dim=self._one_dim)

    def _hull(self, q: np.ndarray, p: int, direction: np.ndarray | None) -> float:
        self._hulls += 1
        return self.world.pair_distance(q, p, kind="hulls", direction=direction)

    def _part(self, q: np.ndarray, p: int) -> float:
        e = self.world.pair_distance(q, p, kind="parts")
        self._parts += bool(np.isfinite(e))  # -inf: the pair has no parts, none asked
        return e

    def _exact_distance(self, q: np.ndarray, p: int) -> float:
        self._exact += 1
        return self.world.pair_distance(q, p)
