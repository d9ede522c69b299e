"""Part hulls: a cheap, tight distance bound for pairs involving a concave mesh.

A concave CAD link (the course's base, with a hollow the claw reaches into) lies inside
its convex hull, but near the hollow that hull touches the other body while the meshes
stay centimetres apart: the hull bound (:mod:`.hulls`) is then 0 and FCL's exact
distance (0.6-4 ms a query on the course's base) was the only bound left. Here the mesh's
triangles (long slivers cut to short pieces first) are split into spatially compact
clusters (median splits of the piece centroids along their longest extent, as the OBB
trees' build, the cluster whose hull strays farthest from its pieces first), each held
by the convex hull of its vertices (a *part*). Every piece lies in its part, so the
parts' union holds the mesh's surface, and the smallest distance over part pairs never
exceeds the meshes' (FCL's distance between two meshes is between their triangles).

A pair query (:func:`parts_bound`) descends the two parts' trees of bounding spheres
together, and only the part pairs that could be the closest are tried: along their
centres' line, the best pair's direction, then GJK's (:mod:`.gjk`). As for the hulls,
GJK only steers a direction ``n``: each part pair's bound is its separation along ``n``
(:func:`.hulls.separation`), a lower bound for *any* unit ``n``, so an early or wrong
GJK stop can only loosen the bound, never make it exceed the distance.

A body whose hull hardly strays from its triangles (a primitive obstacle; a link within
``GAP`` of its hull) keeps one part, its hull: the hull bound is already tight there.
"""

from __future__ import annotations

import functools
import heapq
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from arduinobot.planner.cache import ArtifactCache, content_key
from arduinobot.planner.collision.bounds.gjk import gjk_direction
from arduinobot.planner.collision.bounds.hulls import (
    _SLACK,
    Hull,
    _along,
    _box,
    _qhull,
    separation,
)

_log = logging.getLogger(__name__)

#: bump when the part builder changes: cached parts of an older builder are never read
PARTS_VERSION = "4"
# [m] a cluster whose hull strays farther than this from its triangles (sampled at the
# hull's largest facets) is split again (the worst first); a mesh whose whole hull
# strays less keeps one part: its hull
GAP = 0.001
# parts per mesh at most
MAX_PARTS = 256
# a cluster of fewer triangles is not split again
MIN_TRIANGLES = 16
# no piece of a triangle is longer than this fraction of the mesh's diagonal
LONGEST = 1 / 64
# hull facets sampled per cluster for its gap (the largest: where a hull bridges a
# hollow), against at most this many of its triangles (evenly strided: a gap measured
# against fewer is never smaller)
_SAMPLED_FACETS = 32
_SAMPLED_TRIANGLES = 1024
# the integer arrays of a PartPack
_INDEX = ("offsets", "left", "right", "part")


class PartPack(NamedTuple):
    """One body's :class:`Parts` as one argument of compiled code."""

    vertices: np.ndarray
    offsets: np.ndarray
    radii: np.ndarray
    centers: np.ndarray
    reach: np.ndarray
    left: np.ndarray
    right: np.ndarray
    part: np.ndarray


@dataclass(frozen=True, eq=False)
class Parts:
    """One body as convex parts, in the body's frame, under a binary tree of bounding
    spheres (node 0 the root).

    Attributes:
        vertices: shape (m, 3) [m], every part's hull vertices, part ``i``'s
            ``vertices[offsets[i]:offsets[i + 1]]``.
        offsets: shape (k + 1,), ``k`` parts.
        radii: shape (k,) [m]: part ``i``'s share of the body lies within ``radii[i]``
            of its vertices' convex hull (qhull's rounding; a sphere's radius).
        centers: shape (n, 3) [m], each node's sphere's centre ...
        reach: shape (n,) [m], ... and radius, holding every part under the node (their
            radii included).
        left, right: shape (n,), each node's children, -1 for a leaf.
        part: shape (n,), a leaf's part, -1 for an inner node.
    """

    vertices: np.ndarray
    offsets: np.ndarray
    radii: np.ndarray
    centers: np.ndarray
    reach: np.ndarray
    left: np.ndarray
    right: np.ndarray
    part: np.ndarray

    @property
    def count(self) -> int:
        """How many parts."""
        return len(self.radii)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every array by its attribute's name (for a cache)."""
        return {k: getattr(self, k) for k in PartPack._fields}

    def pack(self) -> PartPack:
        """The arrays for compiled code (contiguous, typed as it expects)."""
        return PartPack(*(np.ascontiguousarray(getattr(self, k),
                                               np.int64 if k in _INDEX else float)
                          for k in PartPack._fields))

    @classmethod
    def of(cls, pieces: list[tuple[np.ndarray, float]], left: np.ndarray,
           right: np.ndarray) -> Parts:
        """Parts from (hull vertices shape (m, 3), radius [m]) pairs, the leaves of the
        tree ``left``, ``right`` (shape (n,), -1 at a leaf; node 0 the root) in node
        order."""
        left, right = np.asarray(left, np.int64), np.asarray(right, np.int64)
        part = np.full(len(left), -1, np.int64)
        leaves = np.flatnonzero(left < 0)
        if len(leaves) != len(pieces) or np.any((left < 0) != (right < 0)):
            raise ValueError(f"{len(pieces)} parts for a tree of {len(leaves)} leaves")
        part[leaves] = np.arange(len(leaves))
        verts = [np.asarray(v, float).reshape(-1, 3) for v, _ in pieces]
        radii = np.array([r for _, r in pieces], float)
        under: list[list[int]] = [[] for _ in left]  # the parts under each node
        for node in range(len(left) - 1, -1, -1):  # children come after their parent
            under[node] = [int(part[node])] if part[node] >= 0 else \
                under[left[node]] + under[right[node]]
        centers, reach = np.zeros((len(left), 3)), np.zeros(len(left))
        for node, parts in enumerate(under):
            pts = np.concatenate([verts[i] for i in parts])
            c = (pts.min(axis=0) + pts.max(axis=0)) / 2
            centers[node] = c
            reach[node] = np.sqrt(((pts - c) ** 2).sum(axis=1)).max() + radii[parts].max()
        return cls(np.ascontiguousarray(np.concatenate(verts)),
                   np.cumsum([0] + [len(v) for v in verts]).astype(np.int64), radii,
                   centers, reach, left, right, part)

    @classmethod
    def of_hull(cls, hull: Hull) -> Parts:
        """The one part of a body that is convex enough: its hull."""
        return cls.of([(hull.vertices, hull.radius)], np.array([-1]), np.array([-1]))


# -- building ---------------------------------------------------------------------------

@numba.njit(cache=True, nogil=True)
def _point_triangle(p: np.ndarray, t: np.ndarray) -> float:
    # squared distance from p to triangle t (shape (3, 3)) (Ericson, Real-Time
    # Collision Detection 5.1.5), in scalars: no temporary arrays
    ax, ay, az = t[0, 0], t[0, 1], t[0, 2]
    abx, aby, abz = t[1, 0] - ax, t[1, 1] - ay, t[1, 2] - az
    acx, acy, acz = t[2, 0] - ax, t[2, 1] - ay, t[2, 2] - az
    apx, apy, apz = p[0] - ax, p[1] - ay, p[2] - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    # the nearest point as a + v ab + w ac
    if d1 <= 0.0 and d2 <= 0.0:
        v, w = 0.0, 0.0
    else:
        bpx, bpy, bpz = apx - abx, apy - aby, apz - abz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        cpx, cpy, cpz = apx - acx, apy - acy, apz - acz
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            v, w = 1.0, 0.0
        elif d6 >= 0.0 and d5 <= d6:
            v, w = 0.0, 1.0
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            v, w = d1 / (d1 - d3), 0.0
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            v, w = 0.0, d2 / (d2 - d6)
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            v = 1.0 - w
        else:
            den = va + vb + vc
            if den > 0.0:
                v, w = vb / den, vc / den
            else:  # a degenerate triangle: its first corner (a gap is only a measure)
                v, w = 0.0, 0.0
    dx = apx - v * abx - w * acx
    dy = apy - v * aby - w * acy
    dz = apz - v * abz - w * acz
    return dx * dx + dy * dy + dz * dz


@numba.njit(cache=True, nogil=True)
def _gap(points: np.ndarray, tri: np.ndarray) -> float:
    # the farthest [m] any of ``points`` (shape (s, 3)) lies from the triangles ``tri``
    # (shape (t, 3, 3))
    worst = 0.0
    for i in range(points.shape[0]):
        best = np.inf
        for t in range(tri.shape[0]):
            best = min(best, _point_triangle(points[i], tri[t]))
            if best <= worst:
                break  # this point cannot raise the farthest: the same max, sooner
        worst = max(worst, best)
    return np.sqrt(worst)


def _subdivide(tri: np.ndarray, longest: float) -> np.ndarray:
    """Triangles (shape (t, 3, 3) [m]) cut at their longest edge's midpoint until no
    edge is longer than ``longest`` [m]: the same surface. CAD meshes have slivers half
    a metre long (the course's base); a cluster holding one would have a hull across
    the whole body, so clusters are made of these pieces instead."""
    done = []
    while len(tri):
        edge = np.linalg.norm(tri[:, [1, 2, 0]] - tri, axis=2)  # edge k: corner k to k+1
        k = np.argmax(edge, axis=1)
        long = edge[np.arange(len(tri)), k] > longest
        done.append(tri[~long])
        t, k = tri[long], k[long]
        rows = np.arange(len(t))
        a, b, c = t[rows, k], t[rows, (k + 1) % 3], t[rows, (k + 2) % 3]
        m = (a + b) / 2
        tri = np.concatenate([np.stack([a, m, c], axis=1), np.stack([m, b, c], axis=1)])
    return np.concatenate(done) if done else np.zeros((0, 3, 3))


def _hull_gap(tri: np.ndarray, points: np.ndarray | None = None
              ) -> tuple[np.ndarray, float, float]:
    """The hull of triangles (shape (t, 3, 3) [m]; ``points``, their distinct corners,
    if known): its vertices, radius [m] (qhull's rounding) and gap [m] (how far its
    largest facets' centroids lie from the triangles: where a hull bridges a hollow)."""
    if points is None:
        points = _unique_rows(tri.reshape(-1, 3))[0]
    hv, hf, outside = _qhull(points)
    return hv, _SLACK + outside, _facet_gap(tri, hv[hf])


def _unique_rows(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(a, axis=0, return_inverse=True)`` for points (shape (n, 3)): the
    distinct rows in lexicographic order, and each row's index among them; by a
    lexsort of the columns, several times faster than numpy's sort of the rows as
    records (0.27 s for the 80k-triangle pieces of a shipped link)."""
    order = np.lexsort((a[:, 2], a[:, 1], a[:, 0]))
    s = a[order]
    new = np.empty(len(s), dtype=bool)
    new[:1] = True
    new[1:] = np.any(s[1:] != s[:-1], axis=1)
    inverse = np.empty(len(a), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    return s[new], inverse


def _node_gap(tri: np.ndarray, points: np.ndarray) -> float:
    """:func:`_hull_gap`'s gap alone, for a cluster that may yet be split: its hull's
    rounding (every point against every facet, the most of a split's time on large
    clusters) is measured only for the clusters kept as parts. The same facets as
    ``_qhull``'s (qhull's, in its order; the box where qhull refuses the input), so
    the same gap, but where a hull leaves points farther out than ``_qhull`` trusts
    (never seen: 5e-14 m at most on the course and shipped links)."""
    try:
        hull = ConvexHull(points, qhull_options="Qt")
    except QhullError:
        hv, hf = _box(points)
        return _facet_gap(tri, hv[hf])
    return _facet_gap(tri, points[hull.simplices])


def _facet_gap(tri: np.ndarray, corners: np.ndarray) -> float:
    # how far [m] the centroids of the largest facets (corners shape (f, 3, 3)) lie from
    # the triangles (shape (t, 3, 3), every stride-th of them)
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                   corners[:, 2] - corners[:, 0]), axis=1)
    top = _largest(area, _SAMPLED_FACETS)
    stride = max(1, len(tri) // _SAMPLED_TRIANGLES)
    return float(_gap(np.ascontiguousarray(corners[top].mean(axis=1)),
                      np.ascontiguousarray(tri[::stride])))


def _largest(x: np.ndarray, k: int) -> np.ndarray:
    """The indices of ``x``'s ``k`` largest values, largest first, ties by index: the
    first ``k`` of a stable argsort of ``-x``, in linear time (a hull of a large
    cluster has thousands of facets; the gap samples 32)."""
    if len(x) <= k:
        return np.argsort(-x, kind="stable")
    t = np.partition(x, len(x) - k)[len(x) - k]  # the k-th largest value
    above = np.flatnonzero(x > t)  # fewer than k
    sel = np.concatenate([above, np.flatnonzero(x == t)[:k - len(above)]])
    return sel[np.argsort(-x[sel], kind="stable")]


def _split(centroids: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles ``idx`` (their ``centroids``: shape (t, 3), every triangle's) in two at
    the median of their centroids along their longest extent (as the OBB trees)."""
    c = centroids[idx]
    axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
    mid = len(idx) // 2
    order = np.argpartition(c[:, axis], mid)  # (deterministic: introselect)
    return idx[order[:mid]], idx[order[mid:]]


def build_parts(vertices: np.ndarray, faces: np.ndarray, *, gap: float = GAP,
                max_parts: int = MAX_PARTS) -> Parts:
    """A mesh (vertices shape (v, 3) [m], triangles shape (f, 3)) as parts: clusters of
    its triangles (cut to pieces no longer than ``LONGEST`` of its diagonal), split the
    worst first while a cluster's hull strays more than ``gap`` [m] from its triangles,
    up to ``max_parts``; one part (its hull) where it never strays."""
    v = np.ascontiguousarray(vertices, float)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    hv, r, whole = _hull_gap(v[f])
    if whole <= gap or len(f) < 2 * MIN_TRIANGLES:
        return Parts.of([(hv, r)], np.array([-1]), np.array([-1]))
    tri = _subdivide(v[f], LONGEST * float(np.linalg.norm(np.ptp(v, axis=0))))
    # the pieces' corners by index (np.unique by rows is slow: once, not per cluster)
    corners, ids = _unique_rows(tri.reshape(-1, 3))
    ids = ids.reshape(-1, 3)
    mark = np.zeros(len(corners), dtype=bool)
    centroids = tri.mean(axis=1)

    def corners_of(half: np.ndarray) -> np.ndarray:
        # a cluster's distinct corners, in order (np.unique's, without its sort)
        u = ids[half].ravel()
        mark[u] = True
        out = np.flatnonzero(mark)
        mark[u] = False
        return corners[out]

    # per node: its triangles and hull while a leaf; children once split
    idx: list[np.ndarray] = [np.arange(len(tri))]
    g = _node_gap(tri, corners)
    left, right = [-1], [-1]
    worst = [(-g, 0)]  # a max-heap of leaves by gap
    leaves = 1
    while worst and leaves < max_parts and -worst[0][0] > gap:
        _, node = heapq.heappop(worst)
        if len(idx[node]) < 2 * MIN_TRIANGLES:
            continue  # too small to split: stays a leaf
        for half in _split(centroids, idx[node]):
            g = _node_gap(tri[half], corners_of(half))
            idx.append(half)
            left.append(-1)
            right.append(-1)
            heapq.heappush(worst, (-g, len(idx) - 1))
        left[node], right[node] = len(idx) - 2, len(idx) - 1
        leaves += 1
    pieces = []
    for k in range(len(idx)):
        if left[k] < 0:  # a leaf: a part, with its hull's rounding measured now
            hv, _, outside = _qhull(corners_of(idx[k]))
            pieces.append((hv, _SLACK + outside))
    _log.info("%d-triangle mesh (hull %.1f mm off it): %d parts of %d pieces, worst gap "
              "%.2f mm", len(f), 1e3 * whole, len(pieces), len(tri),
              1e3 * max([-w for w, _ in worst], default=0.0))
    return Parts.of(pieces, np.array(left), np.array(right))


def mesh_parts(vertices: np.ndarray, faces: np.ndarray, hull: Hull,
               cache: ArtifactCache | None = None) -> Parts:
    """:func:`build_parts`, from ``cache`` when the same triangles were split before;
    ``hull`` (the mesh's) stands for a mesh that keeps one part."""
    v = np.ascontiguousarray(vertices, float)
    f = np.ascontiguousarray(faces, np.int64)
    key = content_key([PARTS_VERSION, str(GAP), str(MAX_PARTS), str(MIN_TRIANGLES),
                       str(LONGEST), v, f]) if cache is not None else ""
    hit = cache.load("part-hulls", key) if cache is not None else None
    if hit is not None:
        parts = Parts(**{k: np.asarray(a) for k, a in hit.items()})
    else:
        parts = build_parts(v, f)
        if cache is not None:
            cache.store("part-hulls", key, parts.arrays())
    return parts if parts.count > 1 else Parts.of_hull(hull)


# -- querying ---------------------------------------------------------------------------

@numba.njit(cache=True, nogil=True)
def _sphere_gap(wa: np.ndarray, ea: np.ndarray, i: int, wb: np.ndarray, eb: np.ndarray,
                j: int) -> float:
    dx, dy, dz = wa[i, 0] - wb[j, 0], wa[i, 1] - wb[j, 1], wa[i, 2] - wb[j, 2]
    return np.sqrt(dx * dx + dy * dy + dz * dz) - ea[i] - eb[j]


@numba.njit(cache=True, nogil=True)
def _placed(c: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = np.empty_like(c)
    for i in range(c.shape[0]):
        for r in range(3):
            out[i, r] = t[r, 0] * c[i, 0] + t[r, 1] * c[i, 1] + t[r, 2] * c[i, 2] + t[r, 3]
    return out


@numba.njit(cache=True, nogil=True)
def parts_bound(a: PartPack, ta: np.ndarray, b: PartPack, tb: np.ndarray,
                cap: float) -> float:
    """A lower bound [m] on the distance between two bodies held by parts ``a`` and
    ``b`` (:class:`PartPack`) at poses ``ta``, ``tb`` (shape (4, 4)), at most ``cap``
    [m] (nothing farther apart is looked at).

    The two sphere trees are descended together, nearer node pairs first; a node pair
    whose spheres are no nearer than the best part pair so far is passed over (every
    part under it is at least that far away), so the result is the least bound over
    every part pair: a part pair's separation along its centres' line, along the best
    pair's direction, or along GJK's, whichever is first not beaten."""
    va, oa, ra, ca, ea, la, ga, pa_ = a
    vb, ob, rb, cb, eb, lb, gb, pb_ = b
    wa, wb = _placed(ca, ta), _placed(cb, tb)
    # depth first: at most one node pair per level of either tree is left waiting
    size = ca.shape[0] + cb.shape[0] + 4
    stack = np.empty((size, 2), np.int64)
    gaps = np.empty(size)
    stack[0, 0], stack[0, 1] = 0, 0
    gaps[0] = _sphere_gap(wa, ea, 0, wb, eb, 0)
    top = 1
    best = cap
    n, nbest = np.empty(3), np.empty(3)
    found = False
    xa, yb = np.empty(3), np.empty(3)
    while top > 0:
        top -= 1
        i, j = stack[top, 0], stack[top, 1]
        if gaps[top] >= best:
            continue  # every part pair under it is at least this far apart
        if pa_[i] >= 0 and pb_[j] >= 0:  # two parts
            pi, pj = pa_[i], pb_[j]
            pa = va[oa[pi]:oa[pi + 1]]
            pb = vb[ob[pj]:ob[pj + 1]]
            slack = ra[pi] + rb[pj]
            # the separation along the centres' line first: it often rules them out
            for r in range(3):
                n[r] = wa[i, r] - wb[j, r]
            norm = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
            if norm > 0.0:
                for r in range(3):
                    n[r] /= norm
            else:
                n[0], n[1], n[2] = 0.0, 0.0, 1.0
            d = _along(pa, ta, pb, tb, n, xa, yb) - slack
            if d < best and found:
                # the best pair's direction: neighbouring pairs often lie apart along it
                d = max(d, _along(pa, ta, pb, tb, nbest, xa, yb) - slack)
            if d < best and gjk_direction(pa, ta, pb, tb, n):
                d = max(d, _along(pa, ta, pb, tb, n, xa, yb) - slack)
                if d < best:
                    nbest[:] = n
                    found = True
            best = min(best, d)
            continue
        # open the larger sphere (a leaf stays)
        if pb_[j] >= 0 or (pa_[i] < 0 and ea[i] >= eb[j]):
            i1, j1, i2, j2 = la[i], j, ga[i], j
        else:
            i1, j1, i2, j2 = i, lb[j], i, gb[j]
        g1 = _sphere_gap(wa, ea, i1, wb, eb, j1)
        g2 = _sphere_gap(wa, ea, i2, wb, eb, j2)
        if g1 < g2:  # the nearer one on top: popped first
            i1, j1, g1, i2, j2, g2 = i2, j2, g2, i1, j1, g1
        if g1 < best:
            stack[top, 0], stack[top, 1], gaps[top] = i1, j1, g1
            top += 1
        if g2 < best:
            stack[top, 0], stack[top, 1], gaps[top] = i2, j2, g2
            top += 1
    return best


class PartBounds:
    """Part-hull distance bounds between the bodies of one world (index order of its
    bodies), each body's parts got on first use.

    Args:
        parts: per body, how to get its parts (a convex body's: its hull alone).
    """

    def __init__(self, parts: Sequence[Callable[[], Parts]]) -> None:
        self._get = list(parts)
        self._packs: list[PartPack | None] = [None] * len(parts)

    def _pack(self, a: int) -> PartPack:
        found = self._packs[a]
        if found is None:
            found = self._packs[a] = self._get[a]().pack()
        return found

    def split(self, a: int, b: int) -> bool:
        """Whether body ``a`` or ``b`` has more than one part (else their hulls' bound
        is as good)."""
        return len(self._pack(a).radii) > 1 or len(self._pack(b).radii) > 1

    def bound(self, a: int, ta: np.ndarray, b: int, tb: np.ndarray, *,
              cap: float = np.inf) -> float:
        """A lower bound [m] on the distance between bodies ``a`` and ``b`` at poses
        ``ta``, ``tb`` (shape (4, 4)), at most ``cap`` [m]; 0 or less where some of their
        parts touch."""
        return float(parts_bound(self._pack(a), np.ascontiguousarray(ta, float),
                                 self._pack(b), np.ascontiguousarray(tb, float),
                                 float(cap)))


@functools.cache
def load_kernels() -> None:
    """Call the near-contact rungs' compiled kernels once a process (the hulls' separation, the
    part hulls' descent and GJK) on two unit cubes, so they are loaded from numba's
    cache now: first called in a process near a contact, they took 8 and 28 ms (more on
    a loaded machine) inside a proof. A service's zygote calls this (through the first
    :class:`.certify.Certifier`) before it forks its workers."""
    cube = np.ascontiguousarray(np.array(np.meshgrid([0.0, 1.0], [0.0, 1.0], [0.0, 1.0]),
                                         float).reshape(3, -1).T)
    here, there = np.eye(4), np.eye(4)
    there[0, 3] = 2.0
    fixed = there.copy()
    fixed.flags.writeable = False  # a static obstacle's pose (a type of its own to numba)
    pack = Parts.of([(cube, 0.0)], np.array([-1]), np.array([-1])).pack()
    for tb in (there, fixed):  # two links; a link and an obstacle
        separation(cube, here, cube, tb, np.array([-1.0, 0.0, 0.0]))
        parts_bound(pack, here, pack, tb, float(np.inf))
