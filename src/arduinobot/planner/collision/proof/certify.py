"""Certified collision checking over continuous motions, not at samples.

A motion is a sequence of pieces in joint space, each ``q(sigma) = start + u1 sigma +
(u2 - u1) L H(sigma / L)`` for ``sigma`` in [0, L] with ``H(x) = x^3 - x^4 / 2``: a
straight edge when ``u1 == u2``, a corner blend of :mod:`arduinobot.planner.timing.curve` otherwise. Along
a piece every joint's speed ``|q_k'(sigma)|`` stays between ``|u1_k|`` and ``|u2_k|`` (the
tangent moves from ``u1`` to ``u2`` by a smoothstep), so a point of one body moves
relative to another by at most ``speed = sum_k weight_k max(|u1_k|, |u2_k|)`` per unit of
``sigma`` (``weight`` [m/rad] from :func:`arduinobot.planner.collision.proof.advance.pair_weights`).

Conservative advancement per checked pair: at ``sigma``, the OBB trees give a lower bound
``d`` on the pair's distance; no point of the next ``(d - covered) / speed`` of the piece
comes closer than ``covered`` (for a body moving by a static one, the step may come from
how fast it moves where it is now instead, :mod:`.body_speed`, when that is longer).
Where ``d`` proves little, the near-contact ladder (:mod:`.ladder`) gives a closer
bound: the convex hulls (along the pair's last GJK direction inside the walk while that
proves it, else a new GJK query), the part hulls, FCL's exact distance (a bound too);
where even that is not above the clearance, the motion is refused at that point.
Every point of every piece is covered, so a motion certified free is free over the whole
continuum, not only where it was sampled.

The walk runs in numba, one call for the whole motion and every pair; Python only
computes the hull and FCL distances near contact (FCL stays the reference for exact
contact).

A pair of links whose relative motion is one-dimensional (the two fingers along their
mimic) is proven before the walk, over cells of that joint kept for every request
(:mod:`.one_dim`), and the walk passes over it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numba
import numpy as np

from arduinobot.planner.collision.bounds.hulls import HullPack, warm_bound
from arduinobot.planner.collision.bounds.obbtree import Forest
from arduinobot.planner.collision.bounds.parts import load_kernels
from arduinobot.planner.collision.compiled import Direct
from arduinobot.planner.collision.proof.advance import Work, tree_lower_bound
from arduinobot.planner.collision.proof.body_speed import local_rates, local_step
from arduinobot.planner.collision.proof.certificate import Certificate
from arduinobot.planner.collision.proof.ladder import (
    GAP,
    HOLD,
    MAX_EXACT,
    MAX_NEAR,
    SOFT,
    STILL,
    Ladder,
)
from arduinobot.planner.collision.proof.nearness import walk_order
from arduinobot.planner.collision.proof.one_dim import OneDimProver
from arduinobot.planner.collision.proof.resume import Motion, Proof, Status, Stop, new_walk
from arduinobot.planner.collision.table import Bodies, Pairs, place_carried
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.chain import Chain, _fk_into

# The walk's own constants (the near-contact ladder's are in :mod:`.ladder`):
# [m] tree bounds are asked to prove at most this much: a deeper proof costs more tree
# descent than the longer step it buys. With a clearance to report, a pair farther apart
# than this is reported at about half of it (15 mm) or more
_CAP = 0.03
# [rad] states this far apart are checked before the proof (see Certifier.pieces): a
# motion that really collides is refused at a sample, not by a walk converging on it
SAMPLE_STEP = 0.01
# distance bounds one certification may evaluate before it gives up (refuses): bounded
# time for a motion that grazes along a contact. The ladder's queries count against it
# too, each as the tree bounds it costs in time (measured in CPU on the Panda: a tree
# bound ~4.5 us; a walk stop, its hull and part-hull queries and the round trip,
# 0.1-0.3 ms; an exact distance 0.1 ms by a box's surface, 0.3-4 ms between CAD links),
# so the budget bounds the whole proof's time
MAX_BOUNDS = 500_000
STOP_COST = 50
EXACT_COST = 200
# a bound carried over from the last piece is used while at least this fraction of the
# last one measured (else a new one is measured: it may be larger, and prove longer steps)
CARRY = 0.5
# tree levels whose nodes stand in for a moving body in its local speed: a step near a
# contact costs an exact distance, so a tighter speed (eight pieces) pays for itself
LOCAL_DEPTH = 3

@numba.njit(cache=True, nogil=True, inline="always")
def _eval_piece(start: np.ndarray, u1: np.ndarray, u2: np.ndarray, length: float,
                sigma: float, out: np.ndarray) -> None:
    x = sigma / length if length > 0 else 0.0
    h = x * x * x - 0.5 * x * x * x * x
    for j in range(start.shape[0]):
        out[j] = start[j] + u1[j] * sigma + (u2[j] - u1[j]) * length * h


@numba.njit(cache=True, nogil=True)
def _advance(motion: Motion, walk: np.ndarray, chain: Chain, bodies: Bodies, pairs: Pairs,
             forest: Forest, hulls: HullPack, clear: float, fraction: float, local: bool,
             work: Work, q: np.ndarray, proof: Proof, exact_below: np.ndarray,
             ask: np.ndarray, order: np.ndarray, max_bounds: int) -> int:
    """Walk pairs ``walk.pair..`` along every piece of ``motion`` from (``walk.piece``,
    ``walk.sigma``); ``walk`` is a :data:`.resume.WALK` record.

    ``walk.injected`` >= 0 is a distance bound [m] for that pair at that point (from the
    caller's hull or FCL query). ``proof.best`` gets each pair's certified clearance. A
    pair whose trees failed at its last bound (near contact) with a ``proof.warm``
    direction (from the caller's last hull query; refined in place) tries the hulls
    along it first, the trees only where that does not prove the step, or where it is
    not above ``exact_below[p]`` [m] beyond the clearance (a pair whose hulls are loose
    there: the caller asks the exact distance). A pair flagged in ``ask`` (the
    caller's part hulls beat the trees and the hulls there) is handed back wherever its
    trees prove little, as one with a warm direction.
    Returns ``Status.NEED_BOUND`` with the point in ``walk`` when a point needs a closer
    bound than the trees' and the warm hulls' (a new hull query, else exact),
    ``Status.BUDGET`` when the bounds are spent, else ``Status.DONE``.
    ``walk.bounds`` counts bounds evaluated; ``q`` (dof,) is a work buffer. (The status
    leaves as a plain int: boxing an enum member back into Python costs ~0.1 ms.)
    """
    # unpacked once: taking an array out of a tuple costs a reference count
    starts, u1, u2, lengths = motion
    index, weight, mover = pairs
    best, directions, warm = proof
    poses, stack, gaps = work
    frame, link, pose, carried = bodies.frame, bodies.link, bodies.pose, bodies.carried
    center, axes, half, left, right, root = forest
    parent, origin, jtype, axis, src, scale, offset = chain
    vertices, offsets, radii = hulls
    at = walk[0]
    p0, k0, s0, injected = at.pair, at.piece, at.sigma, at.injected
    # counted here, written back on return (a local stays in a register)
    bounds, trees, warms = at.bounds, at.trees, at.warm
    npiece, dof = starts.shape
    scratch = np.empty((8, 3, 3))
    end = np.empty(dof)
    rates = np.empty((2, dof))  # local_rates' (rate, turn)
    # the smallest clearance certified so far, any pair: no step need prove more (the
    # certified minimum is the same, the steps longer)
    low = np.inf
    for i in range(best.shape[0]):
        low = min(low, best[i])
    for i in range(p0, order.shape[0]):
        p = order[i]
        k = k0 if i == p0 else 0
        s = s0 if i == p0 else 0.0
        inj = injected if i == p0 else -1.0
        a, b = index[p, 0], index[p, 1]
        carry = -1.0  # a bound [m] proven at the start of piece k, if any
        measured = np.inf  # the last bound measured (trees or FCL)
        fresh = np.inf  # the last bound Python injected (a hull query's, or exact)
        # the trees failed here (their leaf boxes overlap though the meshes do not, as
        # they do well before contact on CAD links): the hulls first while they prove it
        near = False
        # the hulls could not beat the trees at this pair's last hull query (a concave
        # body): no other until its trees prove nothing
        flat = False
        while k < npiece:
            length = lengths[k]
            speed = 0.0
            for j in range(dof):
                speed += weight[p, j] * max(abs(u1[k, j]), abs(u2[k, j]))
            if length <= 0.0 or speed <= 0.0:
                k += 1  # this piece does not move the pair relative to itself
                s = 0.0
                carry = -1.0
                continue
            _eval_piece(starts[k], u1[k], u2[k], length, s, q)
            posed = False  # poses are of q
            if inj >= 0.0:
                d = inj
                inj = -1.0
                measured = fresh = d
                near = True
                # a hull query that could not beat the trees is not asked again until
                # the walk needs an exact bound for this pair
                flat = not (warm[p] or ask[p])
            elif s == 0.0 and carry > clear + GAP and carry >= CARRY * measured:
                # what the last piece left proven holds here: no new bound needed (a
                # pair the motion hardly moves keeps one bound for the whole motion)
                d = carry
            else:
                _fk_into(q, parent, origin, jtype, axis, src, scale, offset, poses)
                place_carried(frame, link, pose, carried, poses)
                posed = True
                ta = poses[frame[a]] if frame[a] >= 0 else pose[a]
                tb = poses[frame[b]] if frame[b] >= 0 else pose[b]
                d = -1.0
                if near and warm[p]:
                    # near contact the steps are short and the hulls barely turn: the
                    # last direction still separates them, without a round trip
                    d = warm_bound(vertices, offsets, radii, a, ta, b, tb, directions[p])
                    warms += 1
                if d <= clear + GAP or d < HOLD * fresh or d <= clear + exact_below[p]:
                    # (a warm bound far below the last query's: its direction went stale,
                    # and would lead the steps down geometrically as it turns away)
                    t = tree_lower_bound(ta, root[a], tb, root[b], center, axes, half, left,
                                         right, clear + GAP, _CAP, stack, gaps, scratch)
                    trees += 1
                    near = t <= clear + SOFT
                    d = max(d, t)
                    if near and not flat and d <= clear + SOFT:
                        # The leaf boxes of CAD meshes (long thin triangles) can prove
                        # nothing tens of millimetres before the meshes touch: a small
                        # positive bound would be taken, and the steps would shrink
                        # geometrically toward the boxes' contact (thousands of bounds,
                        # and a clearance certified in microns). A hull query first
                        # (Python: FCL's GJK), whatever the trees proved (in ``injected``)
                        at.pair, at.piece, at.sigma, at.bounds = i, k, s, bounds + 1
                        at.injected = d
                        at.trees, at.warm = trees, warms
                        return Status.NEED_BOUND.value
                bounds += 1
                if d <= clear + GAP:
                    at.pair, at.piece, at.sigma, at.bounds = i, k, s, bounds
                    at.injected = d
                    at.trees, at.warm = trees, warms
                    return Status.NEED_BOUND.value
                if bounds > max_bounds:
                    at.pair, at.piece, at.sigma, at.bounds = i, k, s, bounds
                    at.trees, at.warm = trees, warms
                    return Status.BUDGET.value
                measured = d
            covered = max(clear + GAP / 2, min(fraction * d, low))
            reach = (d - covered) / speed
            left_on_piece = length - s
            if local and reach < left_on_piece:
                # a body moving by a static one: how fast it moves where it is now
                mov = mover[p]
                if mov >= 0:
                    if not posed:
                        _fk_into(q, parent, origin, jtype, axis, src, scale, offset, poses)
                        place_carried(frame, link, pose, carried, poses)
                    local_rates(poses, poses[frame[mov]], link[mov], root[mov], LOCAL_DEPTH,
                                center, half, left, right, parent, jtype, axis, src, scale,
                                rates)
                    reach = max(reach, local_step(rates[0], rates[1], u1[k], u2[k], speed,
                                                  d - covered))
            carry = -1.0
            if reach >= left_on_piece:
                # the rest of the piece is covered with room to spare
                covered = max(covered, d - speed * left_on_piece)
                carry = d - speed * left_on_piece
                if k + 1 < npiece:
                    # the next piece starts where this one ends, or the gap counts
                    _eval_piece(starts[k], u1[k], u2[k], length, length, end)
                    for j in range(dof):
                        carry -= weight[p, j] * abs(starts[k + 1, j] - end[j])
                k += 1
                s = 0.0
            else:
                s += reach
            if covered < best[p]:
                best[p] = covered
                low = min(low, covered)
    at.bounds, at.trees, at.warm = bounds, trees, warms
    return Status.DONE.value


class Certifier:
    """Certifies motions in one :class:`CollisionWorld` (its robot, scene, padding and
    allowed pairs). The required clearance is the world's padding.

    Args:
        fraction: a step covers down to ``max(clearance, fraction * d)``: 0 proves
            freedom with the fewest bounds; 0.5 also certifies a useful clearance
            (every point at least half its nearest bound) for twice the bounds.
        local: a body moving by a static one also steps by how fast it moves where it
            is now (:mod:`.body_speed`), not only by the every-configuration bound.
        max_exact, max_near: one certification's near-contact budgets (exact queries;
            hull and exact queries together): spent, the motion is refused (its
            certificate's failure names where, distance NaN), never passed
            (:data:`.ladder.MAX_EXACT`, :data:`.ladder.MAX_NEAR` by default).
        max_bounds: one certification's whole budget, in tree bounds (trees and warm
            hulls count one each, a walk stop :data:`STOP_COST`, an exact query
            :data:`EXACT_COST`): spent, the motion is refused likewise
            (:data:`MAX_BOUNDS` by default).
    """

    def __init__(self, world: CollisionWorld, *, fraction: float = 0.0,
                 local: bool = True, max_exact: int = MAX_EXACT,
                 max_near: int = MAX_NEAR, max_bounds: int = MAX_BOUNDS) -> None:
        self.world = world
        self.max_exact = int(max_exact)
        self.max_near = int(max_near)
        self.max_bounds = int(max_bounds)
        self.fraction = float(fraction)  # one compiled variant of the walk
        self.local = bool(local)
        self._work = Work.of(world.table.slots)
        self._q = np.empty(world.dof)
        # the walk resumes after every bound Python computes: past numba's dispatcher
        # (:mod:`.compiled`); its arguments are this certifier's and its world's, typed
        # the same on every call
        self._advance = Direct(_advance)
        # the pairs whose relative motion one joint alone makes, proven by cells kept
        # with the robot's geometry (:mod:`.one_dim`)
        self.one_dim = OneDimProver(world, self._work, gap=GAP)
        # the ladder's kernels, once per process (cached): a service builds its
        # certifiers before it forks, and a proof near contact does not pay ~40 ms to
        # load them
        load_kernels()

    def pieces(self, starts: np.ndarray, u1: np.ndarray, u2: np.ndarray,
               lengths: np.ndarray, *, sample_step: float | None = SAMPLE_STEP
               ) -> Certificate:
        """Certify pieces ``q(sigma) = start + u1 sigma + (u2 - u1) L H(sigma / L)``:
        ``starts``, ``u1``, ``u2`` shape (n, dof), ``lengths`` (n,) [rad].

        States ``sample_step`` [rad] apart are checked first: advancement converges only
        geometrically towards a contact, so a motion that really collides is refused at
        its first colliding sample, and the proof runs on motions whose samples are free
        (a graze between samples is then what it settles, with at most
        :data:`.ladder.MAX_EXACT` exact queries). None skips that for motions whose
        states the caller has just checked (a planner's edges): the proof alone decides,
        as soundly."""
        w = self.world
        clear = w.padding
        motion = Motion(np.ascontiguousarray(starts, float).reshape(-1, w.dof),
                        np.ascontiguousarray(u1, float).reshape(-1, w.dof),
                        np.ascontiguousarray(u2, float).reshape(-1, w.dof),
                        np.ascontiguousarray(lengths, float).reshape(-1))
        # 1. a collision at a sample refutes the motion outright
        if sample_step is not None:
            refuted = self._sampled_collision(*motion, sample_step)
            if refuted is not None:
                return refuted
        npair = len(w.table.pair_names)
        # per motion, so a certificate never depends on what was certified before
        proof = Proof(np.full(npair, np.inf), np.zeros((npair, 3)), np.zeros(npair, np.bool_))
        ladder = Ladder(w, clear=clear, max_exact=self.max_exact, max_near=self.max_near)
        # 2. the still and one-joint pairs are proven without the walk, which passes over
        still, pairs = self._proven_before_walk(motion, ladder, proof)
        # 3. the walk proves every other pair along every piece, stopping where a point
        # needs a closer bound than its trees' and warm hulls'; the ladder gives one
        # (nearest first: the smallest clearance found early lengthens every later step)
        order = self._order(motion, pairs)
        walk = new_walk()
        while True:
            status = Status(self._advance.call(motion, walk, w.chain, w.table.bodies, pairs,
                                               w.forest, w.hulls, clear, self.fraction,
                                               self.local, self._work, self._q, proof,
                                               ladder.exact_below, ladder.ask, order,
                                               self._left(ladder)))
            if status == Status.DONE:
                break
            at = Stop.read(walk)
            p, k, s = int(order[at.pair]), at.piece, at.sigma
            pair = w.table.pair_names[p]
            if status == Status.BUDGET or ladder.spent() or at.bounds > self._left(ladder):
                return Certificate(False, clear, 0.0, pair, (k, s, pair, float("nan")),
                                   at.bounds, ladder.exact, ladder.rungs(walk))
            q = np.empty(w.dof)  # the very point the walk stopped at
            _eval_piece(motion.starts[k], motion.u1[k], motion.u2[k], motion.lengths[k], s, q)
            d = ladder.at_stop(q, p, float(walk[0]["injected"]), proof)
            if d <= clear + GAP:  # 4. a contact, or a point closer than the clearance
                proof.best[p] = min(proof.best[p], d)
                return Certificate(False, clear, max(d, 0.0), pair, (k, s, pair, d),
                                   at.bounds, ladder.exact, ladder.rungs(walk))
            walk[0]["injected"] = d
        # 5. certified: other pairs' figures stop at the smallest so far (the walk proves
        # no more): on a tie, the pair whose figure is its own (a still pair's, else the
        # first walked: the later ones stopped at it) is closest
        best = proof.best
        rank = np.empty(npair, np.int64)
        rank[order] = np.arange(npair)
        worst = min(range(npair), key=lambda p: (best[p], p not in still, rank[p]),
                    default=-1)
        cert = float(best[worst]) if npair and np.isfinite(best[worst]) else float("inf")
        return Certificate(True, clear, cert, w.table.pair_names[worst] if npair else None,
                           None, Stop.read(walk).bounds, ladder.exact, ladder.rungs(walk))

    def _left(self, ladder: Ladder) -> int:
        # the walk's bound budget: what the ladder's queries have left of max_bounds
        return self.max_bounds - STOP_COST * ladder.stops - EXACT_COST * ladder.exact

    def _order(self, motion: Motion, pairs: Pairs) -> np.ndarray:
        # the pairs nearest first (:mod:`.nearness`), read at the pieces' starts and the
        # motion's end; with no clearance to report the walk proves only the clearance
        # itself, whatever it found before: index order
        n = len(pairs.index)
        if self.fraction <= 0 or n < 2:
            return np.arange(n, dtype=np.int64)
        starts, u1, u2, lengths = motion
        last = np.empty(self.world.dof)
        _eval_piece(starts[-1], u1[-1], u2[-1], float(lengths[-1]), float(lengths[-1]), last)
        w = self.world
        return walk_order(np.vstack([starts, last]), w.chain, w.table.bodies, pairs,
                          w.forest, self._work)

    def _sampled_collision(self, starts: np.ndarray, u1: np.ndarray, u2: np.ndarray,
                           lengths: np.ndarray, sample_step: float) -> Certificate | None:
        """The refusal at the first colliding sample (states ``sample_step`` [rad]
        apart along each piece), or None when every sample is free."""
        w = self.world
        for k in range(len(starts)):
            # (a pair no piece moves keeps its start distance: the start is a sample)
            n = max(1, int(np.ceil(lengths[k] / sample_step)))
            sig = np.linspace(0.0, lengths[k], n + 1)
            x = sig / lengths[k] if lengths[k] > 0 else np.zeros_like(sig)
            qs = starts[k] + np.outer(sig, u1[k]) + np.outer(
                lengths[k] * (x**3 - 0.5 * x**4), u2[k] - u1[k])
            bad = w.first_invalid(qs)
            if bad >= 0:
                chk = w.check(qs[bad])
                pair = chk.pairs[0] if chk.pairs else ("", "")
                return Certificate(False, w.padding, 0.0, pair,
                                   (k, float(sig[bad]), pair, 0.0), 0, 0)
        return None

    def _proven_before_walk(self, motion: Motion, ladder: Ladder, proof: Proof
                            ) -> tuple[dict[int, float], Pairs]:
        """The pairs proven without the walk, each with its bound [m] (in ``proof`` too):
        the still pairs (only when a clearance is to be reported) and the pairs one joint
        moves; and the checked pairs for the walk, which passes over them."""
        still: dict[int, float] = {}
        if self.fraction > 0:  # a clearance to report: still pairs at their own bound
            still = self._still_pairs(motion, ladder)
        n_still = len(still)
        # pairs one joint moves, proven over its range by cached cells
        for p, d in self.one_dim.proven(*motion).items():
            if p not in still:
                still[p] = d
        ladder.proven_before(still=n_still, one_dim=len(still) - n_still)
        pairs = self.world.table.pairs
        if still:
            idx = np.fromiter(still, np.int64)
            proof.best[idx] = np.fromiter(still.values(), float)
            weight = pairs.weight.copy()
            weight[idx] = 0.0  # proven: the walk passes over them
            weight.flags.writeable = False  # as the table's (one compiled variant)
            pairs = pairs._replace(weight=weight)
        return still, pairs

    def _still_pairs(self, motion: Motion, ladder: Ladder) -> dict[int, float]:
        # The pairs the motion barely moves (the fingers in an arm motion), each with its
        # distance bound at the start (the hulls', tight on convex links; FCL's where they
        # touch) less the most the motion moves it: as sound as a walk (a piece's joint
        # speeds stay within max(|u1|, |u2|); the gaps between pieces count too) and,
        # remembered by the world, free after the first motion. The walk would give half
        # an OBB-tree bound instead (a few tenths of the true distance on CAD meshes)
        # and, as the smallest so far, cap every other pair's.
        starts, u1, u2, lengths = motion
        travel = (lengths[:, None] * np.maximum(np.abs(u1), np.abs(u2))).sum(axis=0)
        ends = starts + lengths[:, None] * (u1 + u2) / 2  # H(1) = 1/2
        travel += np.abs(starts[1:] - ends[:-1]).sum(axis=0)
        moved = self.world.table.pairs.weight @ travel
        out = {}
        above = self.world.padding + GAP
        for p in np.flatnonzero(moved < STILL):
            d = ladder.still_bound(starts[0], int(p), above=above) - moved[p]
            if d > above:  # else the walk decides (and refuses where it must)
                out[int(p)] = d
        return out

    def path(self, path: np.ndarray, *, sample_step: float | None = SAMPLE_STEP
             ) -> Certificate:
        """Certify the polyline through ``path`` (shape (k, dof)) edge by edge."""
        path = np.asarray(path, float).reshape(-1, self.world.dof)
        if len(path) < 2:
            path = np.vstack([path, path])
        d = np.diff(path, axis=0)
        lengths = np.linalg.norm(d, axis=1)
        u = np.divide(d, lengths[:, None], out=np.zeros_like(d), where=lengths[:, None] > 0)
        return self.pieces(path[:-1], u, u, lengths, sample_step=sample_step)

    def curve(self, sections: Sequence[Any]) -> Certificate:
        """Certify every piece of a :class:`arduinobot.planner.timing.curve.Curve`'s sections (anything with
        ``starts``, ``u1``, ``u2`` and ``lengths``) as one motion."""
        if not sections:
            raise ValueError("a curve has at least one section")
        return self.pieces(np.concatenate([c.starts for c in sections]),
                           np.concatenate([c.u1 for c in sections]),
                           np.concatenate([c.u2 for c in sections]),
                           np.concatenate([c.lengths for c in sections]))
