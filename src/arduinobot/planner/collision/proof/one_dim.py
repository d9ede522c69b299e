"""Link pairs whose relative motion is one-dimensional, proven over cells of that joint.

A pair of links whose ``weight`` is zero but for one joint (the two fingers of a gripper
along its mimic, a camera by the turntable) has a distance that is a function of that
joint alone. Such a pair is proven once per cell of that joint's range: the hulls' bound
at the cell's middle, or the trees' where the hulls touch, less ``weight`` times half its
width; cells halved where that does not prove them, and cells proven less than
``CHAIN_BELOW`` proven again from exact distances chained along the joint from a
neighbour proven free. The cells are kept with the robot's geometry (a world's
``bodies``, shared by the worlds of its scenes) for every request, a pair's whole row
at its first motion, and in the robot's artifact cache by content (a worker started
later reads them): a motion whose joint range they cover takes the smallest of their
bounds for the pair, and the certifier's walk passes over it (a few cached cells instead
of a walk of tree bounds, or near contact thousands of tiny steps).

Two links only: their cells hold for every scene of the robot and are few (an obstacle a
link turns past about one axis would want cells over that joint's whole range, one
scene's: measured slower than its walk through the service). A gripper's range is some
160 cells, filled in ~25 ms (once per robot and machine), looked up in ~0.3 ms a motion; walking the
fingers cost 1.5-2.5 ms a proof of arm and gripper together (course_fingers, trees of
6k-triangle fingers ~30 us a bound).
"""

from __future__ import annotations

import numba
import numpy as np

from arduinobot.planner.cache import content_key
from arduinobot.planner.collision.bounds.hulls import warm_bound
from arduinobot.planner.collision.proof.advance import Work, tree_lower_bound
from arduinobot.planner.collision.table import BodyKind
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.kinematics.chain import _fk_into

# [rad] one-dimensional pairs are proven over cells of their joint this wide at first
# (each halved, down to CELL / 2**CELL_LEVELS, where its bound does not prove it)
CELL = 0.01
CELL_LEVELS = 4
# [m] a cell proven less than this beyond the clearance (the closed fingers, whose hulls
# touch: the trees' bound) is proven again from exact distances chained along the joint
# from a neighbour proven free, at states CELL / 2**CHAIN_LEVEL apart
CHAIN_BELOW = 1e-3
CHAIN_LEVEL = 2
# cells a chain may cross to its cell (each costs 2**CHAIN_LEVEL exact distances, once)
CHAIN_REACH = 8
# refinements of a cell's hull direction (each from the extreme points the last one found)
HULL_TRIES = 4
#: bump when the cells' proof changes: rows kept on disk by an older one are never read
CELLS_VERSION = "1"


@numba.njit(cache=True, nogil=True)
def _hull_bound(vertices: np.ndarray, offsets: np.ndarray, radii: np.ndarray, a: int,
                ta: np.ndarray, b: int, tb: np.ndarray, n: np.ndarray, warm: bool) -> float:
    # The hulls' bound [m] of bodies a and b (poses ta, tb) without leaving compiled
    # code: from direction n if ``warm``, else from the line between their frames,
    # refined HULL_TRIES times (each from the extreme points the last one found; n gets
    # the best). Sound along any direction (see warm_bound).
    if not warm:
        norm = 0.0
        for r in range(3):
            n[r] = ta[r, 3] - tb[r, 3]
            norm += n[r] * n[r]
        norm = np.sqrt(norm)
        if norm > 0.0:
            for r in range(3):
                n[r] /= norm
        else:
            n[0], n[1], n[2] = 1.0, 0.0, 0.0
    d = -np.inf
    for _ in range(HULL_TRIES):
        e = warm_bound(vertices, offsets, radii, a, ta, b, tb, n)
        if e <= d:
            break  # no better direction found
        d = e
    return d


@numba.njit(cache=True, nogil=True)
def _hull_at(q: np.ndarray, parent: np.ndarray, origin: np.ndarray, jtype: np.ndarray,
             axis: np.ndarray, src: np.ndarray, scale: np.ndarray, offset: np.ndarray,
             vertices: np.ndarray, offsets: np.ndarray, radii: np.ndarray, a: int, b: int,
             fa: int, fb: int, poses: np.ndarray) -> float:
    # The hulls' bound [m] of link bodies a and b (pose slots fa, fb) at state q: their
    # separation along the line between their frames, refined HULL_TRIES times from the
    # extreme points each direction picks (warm_bound). Sound along any direction.
    _fk_into(q, parent, origin, jtype, axis, src, scale, offset, poses)
    return _hull_bound(vertices, offsets, radii, a, poses[fa], b, poses[fb], np.empty(3),
                       False)


class PairCells:
    """What the proofs keep for one robot's geometry (``bodies.proofs["one_dim"]``).

    Attributes:
        cells: (padding, link, link, level, cell) -> the bound [m] proven over that cell
            (-inf: none).
        rows: (padding, link, link) -> (first cell, each level-0 cell's bound (nan: not
            yet)).
    """

    def __init__(self) -> None:
        self.cells: dict[tuple[float, str, str, int, int], float] = {}
        self.rows: dict[tuple[float, str, str], tuple[int, np.ndarray]] = {}


class OneDimProver:
    """Proves a world's one-dimensional link pairs over a motion's joint range.

    Args:
        world: the collision world (its padding is the clearance).
        work: the certifier's work buffers (pose slots).
        gap: [m] a bound proves a pair when it exceeds the clearance by more than this.
    """

    def __init__(self, world: CollisionWorld, work: Work, *, gap: float) -> None:
        self.world, self._work, self.gap = world, work, float(gap)
        # pair -> the joint that alone moves it (the weights carry a 1e-12 floor: a
        # joint that moves both bodies rigidly is ~0)
        moving = world.table.pairs.weight > 1e-9
        links = world.table.pairs.index
        self.pairs = {p: int(np.flatnonzero(moving[p])[0])
                      for p in range(len(moving)) if moving[p].sum() == 1
                      and world.table.kinds[links[p, 0]] == BodyKind.LINK
                      and world.table.kinds[links[p, 1]] == BodyKind.LINK}
        store = world.bodies.proofs.setdefault("one_dim", PairCells())
        self._cells, self._rows = store.cells, store.rows

    def proven(self, starts: np.ndarray, u1: np.ndarray, u2: np.ndarray,
                      lengths: np.ndarray) -> dict[int, float]:
        """The one-dimensional pairs (see the module) proven over the whole motion, each
        with its bound [m] (above the clearance): over every cell of its joint's range.

        A piece's joint ``k`` stays within ``start_k + L [min(0, u1_k, u2_k), max(0,
        u1_k, u2_k)]`` (its speed lies between ``u1_k`` and ``u2_k``). A cell's bound is
        the convex hulls' at its middle (sound at any state, no contact premise needed;
        where the hulls touch there is none) less the most the pair's distance changes
        within half the cell (``weight``)."""
        if not self.pairs:
            return {}
        lo = (starts + lengths[:, None] * np.minimum(0.0, np.minimum(u1, u2))).min(axis=0)
        hi = (starts + lengths[:, None] * np.maximum(0.0, np.maximum(u1, u2))).max(axis=0)
        out = {}
        for p, j in self.pairs.items():
            # the closed cells [k h, (k + 1) h] that hold [lo, hi] (a motion ending on a
            # cell's edge, such as a closed gripper at its limit, needs no cell beyond)
            first = int(np.floor(lo[j] / CELL))
            last = max(first + 1, int(np.ceil(hi[j] / CELL)))
            d = float(self._row(p, j, first, last, starts[0]).min())
            if d > self.world.padding + self.gap:
                out[p] = d
        return out

    def _row(self, p: int, j: int, first: int, last: int, base: np.ndarray) -> np.ndarray:
        # the bounds of pair p's cells first..last-1 (level 0, each the smallest of its
        # halves where it was split), from a row kept per pair over its joint's range
        # (with an artifact cache whole from the first motion on, else each cell as a
        # motion first reads it): a motion reads a slice (~microseconds)
        key = (self.world.padding, *self.world.pair_names[p])
        row = self._rows.get(key)
        if row is None:
            row = self._rows[key] = self._new_row(p, j, base)
        if first < row[0] or last > row[0] + len(row[1]):
            # (a motion a hair past the limits: its cells beyond are computed as read)
            lo, hi = min(first, row[0]), max(last, row[0] + len(row[1]))
            grown = np.full(hi - lo, np.nan)
            grown[row[0] - lo:row[0] - lo + len(row[1])] = row[1]
            row = self._rows[key] = (lo, grown)
        cells = row[1][first - row[0]:last - row[0]]  # a view: filled in place
        todo = np.flatnonzero(np.isnan(cells))
        for i in todo:
            cells[i] = self._cell(p, j, 0, first + int(i), base)
        for i in todo:
            if not cells[i] > self.world.padding + CHAIN_BELOW:
                self._chain(p, j, row, first + int(i), base)
        return cells

    def _new_row(self, p: int, j: int, base: np.ndarray) -> tuple[int, np.ndarray]:
        # (first cell, bounds) of pair p over its joint's limits. With an artifact
        # cache, every cell proven (and chained where weak) at once and kept there by
        # content, so a worker started later reads them (~1 ms) instead of paying for
        # them over its first requests (~0.4 s in all on course_fingers, 0.37 s of it
        # for a pair whose cells collide at some values); without one, none yet (each
        # proven as a motion first reads it: a library user's worlds pay only for what
        # they read)
        w = self.world
        lim = w.description.robot.position_limits((w.kin.joint_names[j],))[0]
        lo, hi = int(np.floor(lim[0] / CELL)), int(np.ceil(lim[1] / CELL))
        row = (lo, np.full(hi - lo, np.nan))
        cache = w.bodies.cache
        if cache is None:
            return row
        ckey = self._content(p, j, lo, hi)
        hit = cache.load("one-dim-cells", ckey)
        if hit is not None and hit["bounds"].shape == (hi - lo,):
            return lo, np.array(hit["bounds"], dtype=float)
        bounds = row[1]
        for i in range(hi - lo):
            bounds[i] = self._cell(p, j, 0, lo + i, base)
        for i in range(hi - lo):
            if not bounds[i] > w.padding + CHAIN_BELOW:
                self._chain(p, j, row, lo + i, base)
        cache.store("one-dim-cells", ckey, {"bounds": bounds.copy()})
        return row

    def _content(self, p: int, j: int, lo: int, hi: int) -> str:
        # the key of pair p's row: everything its bounds follow from (the two links'
        # geometry as the proofs read it, the whole chain, the pair's weights, the
        # clearance, the cells' settings and the range)
        w = self.world
        parts: list[bytes | str | np.ndarray] = [
            "one-dim-cells", CELLS_VERSION, *w.pair_names[p],
            np.array([w.padding, self.gap, CELL, CELL_LEVELS, CHAIN_BELOW, CHAIN_LEVEL,
                      CHAIN_REACH, HULL_TRIES, j, lo, hi], float),
            *w.chain, np.asarray(w.table.pairs.weight[p])]
        b = w.bodies
        for link in w.pair_names[p]:
            i = b.names.index(link)
            t, h = b.trees[i], b.hulls[i]
            parts += [np.array([b.frames[i], h.radius], float), b.points[i][1],
                      t.center, t.axes, t.half, t.left, t.right, h.vertices]
        return content_key(parts)

    def _chain(self, p: int, j: int, row: tuple[int, np.ndarray], k: int,
               base: np.ndarray) -> None:
        # Cell k (level 0) of pair p proven again, with its neighbours toward the nearest
        # cell of the row proven by more than CHAIN_BELOW: the state at that cell's edge
        # is free (proven), so FCL's exact distance there is a true distance; each step
        # of e = CELL / 2**CHAIN_LEVEL on from a true distance D loses at most w e
        # (``weight``): while D - w e stays above the clearance, the next state is
        # reached without contact and its exact distance is true too. A step between
        # true distances D0 and D1 keeps at least (D0 + D1 - w e) / 2. A cell takes the
        # larger of that and its own bound.
        w, (lo, bounds) = self.world, row
        floor = w.padding + CHAIN_BELOW
        for step in (-1, 1):
            a = k + step
            while 0 <= a - lo < len(bounds) and abs(a - k) <= CHAIN_REACH:
                if np.isnan(bounds[a - lo]):
                    bounds[a - lo] = self._cell(p, j, 0, a, base)
                if bounds[a - lo] > floor:
                    break
                a += step
            else:
                continue  # no proven neighbour this way
            weight = float(w.table.pairs.weight[p, j])
            e = CELL / 2**CHAIN_LEVEL
            per = 2**CHAIN_LEVEL
            q = np.array(base, dtype=float)
            # from the anchor's edge toward k: cells a - step, ..., k
            edge = (a + 1) * CELL if step < 0 else a * CELL  # the anchor's, facing k
            q[j] = edge
            d0 = w.pair_distance(q, p)
            c = a - step
            while True:
                kept = np.inf
                for i in range(1, per + 1):
                    if not d0 - weight * e > w.padding + self.gap:
                        return  # the chain stops: no later state is known free
                    q[j] = edge - step * i * e
                    d1 = w.pair_distance(q, p)
                    kept = min(kept, (d0 + d1 - weight * e) / 2)
                    d0 = d1
                edge -= step * CELL
                bounds[c - lo] = max(bounds[c - lo], kept)
                if c == k:
                    return
                c -= step

    def _cell(self, p: int, j: int, level: int, k: int, base: np.ndarray) -> float:
        # the bound proven for pair p over joint j's cell [k h, (k + 1) h], h = CELL /
        # 2**level; halved where it fails. ``base``: any state (the other joints move the
        # pair's bodies together: the pair's distance does not depend on them).
        key = (self.world.padding, *self.world.pair_names[p], level, k)
        got = self._cells.get(key)
        if got is not None:
            return got
        w = self.world
        h = CELL / 2**level
        q = np.array(base, dtype=float)
        q[j] = (k + 0.5) * h
        change = float(w.table.pairs.weight[p, j]) * h / 2  # [m] within half the cell
        need = w.padding + self.gap + change
        # the hulls' separation along a few refined directions, or the trees' whole
        # bound where the hulls touch (closed fingers): both sound at any state (an
        # exact distance would hold only at a state reached without contact, which the
        # middle of a cell need not be), microseconds each
        a, b = (int(x) for x in w.table.pairs.index[p])
        c, hp, frame, f = w.chain, w.hulls, w.table.bodies.frame, w.forest
        wk = self._work
        d = _hull_at(q, c.parent, c.origin, c.jtype, c.axis, c.src, c.scale, c.offset,
                     hp.vertices, hp.offsets, hp.radii, a, b, int(frame[a]), int(frame[b]),
                     wk.poses)
        if not d > need:  # (_hull_at left the poses of q in the work buffer)
            d = max(d, tree_lower_bound(wk.poses[frame[a]], f.root[a], wk.poses[frame[b]],
                                        f.root[b], f.center, f.axes, f.half, f.left,
                                        f.right, need, 1.0, wk.stack, wk.gaps,
                                        np.empty((8, 3, 3))))
        bound = d - change if d > need else -np.inf
        if bound == -np.inf and level < CELL_LEVELS:
            bound = min(self._cell(p, j, level + 1, 2 * k, base),
                        self._cell(p, j, level + 1, 2 * k + 1, base))
        self._cells[key] = bound
        return bound
