"""Part hulls: a cheap, tight distance bound for pairs involving a concave mesh.

A concave CAD link (the course's base, with a hollow the claw reaches into) lies inside
its convex hull, but near the hollow that hull touches the other body while the meshes
stay centimetres apart: the hull bound (:mod:`.hulls`) is then 0 and FCL's exact
distance (0.6-4 ms a query on the course's base) was the only bound left. Here the mesh's
triangles are split into spatially compact clusters (median splits of the triangle
centroids along the longest axis, as the OBB trees' build, while a cluster's hull strays
from its triangles), each cluster held by the convex hull of its vertices (a *part*).
Every triangle lies in its part, so the parts' union holds the mesh's surface, and the
smallest distance over part pairs never exceeds the meshes' (FCL's distance between two
meshes is between their triangles).

A pair query (:func:`parts_bound`) culls part pairs by bounding spheres and by the
separation along their centres' line, and only the part pairs that could be the
closest get a GJK run (here in numba, on the parts' vertices). As for the hulls, GJK only
steers a direction ``n``: each part pair's bound is its separation along ``n``
(:func:`.hulls.separation`), a lower bound for *any* unit ``n``, so an early or wrong
GJK stop can only loosen the bound, never make it exceed the distance.

A body whose hull hardly strays from its triangles (a finger, a primitive) keeps one
part, its hull: the hull bound is already tight there.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numba
import numpy as np

from ..cache import ArtifactCache, content_key
from .hulls import _SLACK, Hull, _along, _qhull

_log = logging.getLogger(__name__)

#: bump when the part builder changes: cached parts of an older builder are never read
PARTS_VERSION = "1"
# [m] a mesh whose hull strays less than this from its triangles (sampled at the hull's
# largest facets) keeps one part: its hull
GAP = 0.001
# parts per mesh (a power of two)
PARTS = 128
# a cluster of fewer triangles is not split again
MIN_TRIANGLES = 16
# no piece of a triangle is longer than this fraction of the mesh's diagonal
LONGEST = 1 / 64
# hull facets sampled per cluster for its gap (the largest: where a hull bridges a hollow)
_SAMPLED_FACETS = 64
# GJK: iterations at most, and the relative progress below which it stops
_GJK_ITERATIONS = 48
_GJK_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class Parts:
    """One body as convex parts, in the body's frame.

    Attributes:
        vertices: shape (m, 3) [m], every part's hull vertices, part ``i``'s
            ``vertices[offsets[i]:offsets[i + 1]]``.
        offsets: shape (k + 1,).
        radii: shape (k,) [m]: part ``i``'s share of the body lies within ``radii[i]``
            of its vertices' convex hull (qhull's rounding; a sphere's radius).
        centers: shape (k, 3) [m], a centre per part ...
        reach: shape (k,) [m], ... within which the whole part (radius included) lies.
    """

    vertices: np.ndarray
    offsets: np.ndarray
    radii: np.ndarray
    centers: np.ndarray
    reach: np.ndarray

    @property
    def count(self) -> int:
        """How many parts."""
        return len(self.radii)

    @classmethod
    def of(cls, pieces: list[tuple[np.ndarray, float]]) -> Parts:
        """Parts from (hull vertices shape (m, 3), radius [m]) pairs."""
        verts = [np.asarray(v, float).reshape(-1, 3) for v, _ in pieces]
        centers = np.array([(v.min(axis=0) + v.max(axis=0)) / 2 for v in verts]).reshape(-1, 3)
        radii = np.array([r for _, r in pieces], float)
        reach = np.array([np.sqrt(((v - c) ** 2).sum(axis=1)).max() + r
                          for v, c, r in zip(verts, centers, radii)], float)
        return cls(np.ascontiguousarray(np.concatenate(verts) if verts else np.zeros((0, 3))),
                   np.cumsum([0] + [len(v) for v in verts]).astype(np.int64),
                   radii, np.ascontiguousarray(centers), reach)

    @classmethod
    def of_hull(cls, hull: Hull) -> Parts:
        """The one part of a body that is convex enough: its hull."""
        return cls.of([(hull.vertices, hull.radius)])


# -- building ---------------------------------------------------------------------------

@numba.njit(cache=True, nogil=True)
def _point_triangle(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    # squared distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5)
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0.0 and d2 <= 0.0:
        q = a
    else:
        bp = p - b
        d3, d4 = ab @ bp, ac @ bp
        if d3 >= 0.0 and d4 <= d3:
            q = b
        else:
            cp = p - c
            d5, d6 = ab @ cp, ac @ cp
            vc = d1 * d4 - d3 * d2
            vb = d5 * d2 - d1 * d6
            va = d3 * d6 - d5 * d4
            if d6 >= 0.0 and d5 <= d6:
                q = c
            elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                q = a + ab * (d1 / (d1 - d3))
            elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                q = a + ac * (d2 / (d2 - d6))
            elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                q = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
            else:
                den = va + vb + vc
                if den <= 0.0:  # a degenerate triangle: its nearest vertex
                    q = a
                    if (p - b) @ (p - b) < (p - q) @ (p - q):
                        q = b
                    if (p - c) @ (p - c) < (p - q) @ (p - q):
                        q = c
                else:
                    q = a + ab * (vb / den) + ac * (vc / den)
    d = p - q
    return d @ d


@numba.njit(cache=True, nogil=True)
def _gap(points: np.ndarray, tri: np.ndarray) -> float:
    # the farthest [m] any of ``points`` (shape (s, 3)) lies from the triangles ``tri``
    # (shape (t, 3, 3))
    worst = 0.0
    for i in range(points.shape[0]):
        best = np.inf
        for t in range(tri.shape[0]):
            best = min(best, _point_triangle(points[i], tri[t, 0], tri[t, 1], tri[t, 2]))
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


def _hull_gap(tri: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The hull of triangles (shape (t, 3, 3) [m]): its vertices, radius [m] (qhull's
    rounding) and gap [m] (how far its largest facets' centroids lie from the
    triangles: where a hull bridges a hollow)."""
    hv, hf, outside = _qhull(np.unique(tri.reshape(-1, 3), axis=0))
    corners = hv[hf]  # (f, 3, 3)
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                   corners[:, 2] - corners[:, 0]), axis=1)
    top = np.argsort(-area, kind="stable")[:_SAMPLED_FACETS]
    gap = _gap(np.ascontiguousarray(corners[top].mean(axis=1)), np.ascontiguousarray(tri))
    return hv, _SLACK + outside, float(gap)


def _split(cent: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # at the median of the centroids along their longest extent (as the OBB trees)
    c = cent[tris]
    axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
    order = np.argsort(c[:, axis], kind="mergesort")
    mid = len(tris) // 2
    return tris[order[:mid]], tris[order[mid:]]


def build_parts(vertices: np.ndarray, faces: np.ndarray, *, gap: float = GAP,
                count: int = PARTS) -> Parts:
    """A mesh (vertices shape (v, 3) [m], triangles shape (f, 3)) as ``count`` parts
    (a power of two: balanced median splits), or one (its hull) where that hull strays
    no more than ``gap`` [m] from the triangles."""
    v = np.ascontiguousarray(vertices, float)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    hv, r, g = _hull_gap(v[f])
    if g <= gap or len(f) < 2 * MIN_TRIANGLES:
        return Parts.of([(hv, r)])
    tri = _subdivide(v[f], LONGEST * float(np.linalg.norm(np.ptp(v, axis=0))))
    cent = tri.mean(axis=1)
    clusters = [np.arange(len(tri))]
    while len(clusters) < count and min(map(len, clusters)) >= 2 * MIN_TRIANGLES:
        clusters = [half for c in clusters for half in _split(cent, c)]
    pieces = []
    for c in clusters:
        hv, hf, outside = _qhull(np.unique(tri[c].reshape(-1, 3), axis=0))
        pieces.append((hv, _SLACK + outside))
    _log.info("%d-triangle mesh (hull %.1f mm off it): %d parts of %d pieces", len(f),
              1e3 * g, len(pieces), len(tri))
    return Parts.of(pieces)


def mesh_parts(vertices: np.ndarray, faces: np.ndarray, hull: Hull,
               cache: ArtifactCache | None = None) -> Parts:
    """:func:`build_parts`, from ``cache`` when the same triangles were split before;
    ``hull`` (the mesh's) stands for a mesh that keeps one part."""
    v = np.ascontiguousarray(vertices, float)
    f = np.ascontiguousarray(faces, np.int64)
    key = content_key([PARTS_VERSION, str(GAP), str(PARTS), str(MIN_TRIANGLES),
                       str(LONGEST), v, f]) \
        if cache is not None else ""
    hit = cache.load("part-hulls", key) if cache is not None else None
    if hit is not None:
        parts = Parts(hit["vertices"], hit["offsets"], hit["radii"], hit["centers"],
                      hit["reach"])
    else:
        parts = build_parts(v, f)
        if cache is not None:
            cache.store("part-hulls", key, {"vertices": parts.vertices,
                                            "offsets": parts.offsets, "radii": parts.radii,
                                            "centers": parts.centers, "reach": parts.reach})
    return parts if parts.count > 1 else Parts.of_hull(hull)


# -- querying ---------------------------------------------------------------------------

@numba.njit(cache=True, nogil=True)
def _support(v: np.ndarray, t: np.ndarray, d: np.ndarray, out: np.ndarray) -> None:
    # the world point of vertices ``v`` placed by ``t`` farthest along world ``d``
    m0 = t[0, 0] * d[0] + t[1, 0] * d[1] + t[2, 0] * d[2]
    m1 = t[0, 1] * d[0] + t[1, 1] * d[1] + t[2, 1] * d[2]
    m2 = t[0, 2] * d[0] + t[1, 2] * d[1] + t[2, 2] * d[2]
    best, k = -np.inf, 0
    for i in range(v.shape[0]):
        x = v[i, 0] * m0 + v[i, 1] * m1 + v[i, 2] * m2
        if x > best:
            best, k = x, i
    for r in range(3):
        out[r] = t[r, 0] * v[k, 0] + t[r, 1] * v[k, 1] + t[r, 2] * v[k, 2] + t[r, 3]


@numba.njit(cache=True, nogil=True)
def _det3(g: np.ndarray) -> float:
    return (g[0, 0] * (g[1, 1] * g[2, 2] - g[1, 2] * g[2, 1])
            - g[0, 1] * (g[1, 0] * g[2, 2] - g[1, 2] * g[2, 0])
            + g[0, 2] * (g[1, 0] * g[2, 1] - g[1, 1] * g[2, 0]))


@numba.njit(cache=True, nogil=True)
def _closest(w: np.ndarray, count: int, v: np.ndarray, scratch: np.ndarray) -> int:
    # The point of the simplex w[:count] (count <= 4, the newest point last) nearest the
    # origin into v; the simplex reduced in place to the smallest face holding it;
    # returns the new count. The faces holding the newest point are tried (GJK's nearest
    # point always lies on one: the older points' own nearest was v's last value): the
    # nearest point is the least-norm one among faces whose origin projection lies
    # inside them (all barycentrics >= 0). ``scratch``: shape (8, 3), a work buffer.
    best = np.inf
    keep = 0
    g, h = scratch[0:3], scratch[3:6]
    rhs, mu = scratch[6], scratch[7]
    idx = np.empty(4, np.int64)
    lam = np.empty(4)
    newest = count - 1
    for mask in range(1 << newest):
        k = 0
        for i in range(newest):
            if mask & (1 << i):
                idx[k] = i
                k += 1
        idx[k] = newest
        k += 1
        p0 = w[newest]
        lam[:k] = 0.0
        n = k - 1
        # minimise |p0 + sum mu_i e_i|^2: G mu = -E^T p0 (E's columns e_i = p_i - p0,
        # over the face's other points)
        for i in range(n):
            rhs[i] = 0.0
            for c in range(3):
                rhs[i] -= (w[idx[i], c] - p0[c]) * p0[c]
            for j in range(n):
                acc = 0.0
                for c in range(3):
                    acc += (w[idx[i], c] - p0[c]) * (w[idx[j], c] - p0[c])
                g[i, j] = acc
        if n == 1:
            if g[0, 0] <= 1e-30:
                continue
            mu[0] = rhs[0] / g[0, 0]
        elif n == 2:
            det = g[0, 0] * g[1, 1] - g[0, 1] * g[1, 0]
            if abs(det) <= 1e-30:
                continue
            mu[0] = (rhs[0] * g[1, 1] - g[0, 1] * rhs[1]) / det
            mu[1] = (g[0, 0] * rhs[1] - rhs[0] * g[1, 0]) / det
        elif n == 3:
            det = _det3(g)
            if abs(det) <= 1e-30:
                continue
            for c in range(3):  # Cramer's rule: column c replaced by rhs
                h[:, :] = g
                for r in range(3):
                    h[r, c] = rhs[r]
                mu[c] = _det3(h) / det
        s = 0.0
        ok = True
        for i in range(n):
            ok = ok and mu[i] >= 0.0
            lam[i] = mu[i]
            s += mu[i]
        lam[n] = 1.0 - s  # the newest point's
        if not ok or lam[n] < 0.0:
            continue
        x0, x1, x2 = 0.0, 0.0, 0.0
        for i in range(k):
            x0 += lam[i] * w[idx[i], 0]
            x1 += lam[i] * w[idx[i], 1]
            x2 += lam[i] * w[idx[i], 2]
        dd = x0 * x0 + x1 * x1 + x2 * x2
        if dd < best:
            best = dd
            keep = mask | (1 << newest)
            v[0], v[1], v[2] = x0, x1, x2
    # reduce the simplex to the kept face, in order (the newest stays last)
    k = 0
    for i in range(count):
        if keep & (1 << i):
            w[k] = w[i]
            k += 1
    return k


@numba.njit(cache=True, nogil=True)
def gjk_direction(va: np.ndarray, ta: np.ndarray, vb: np.ndarray, tb: np.ndarray,
                  n: np.ndarray) -> bool:
    """GJK on the convex hulls of ``va`` placed by ``ta`` and ``vb`` by ``tb`` (shapes
    (m, 3), poses (4, 4)): ``n`` (shape (3,), in: a start direction from b towards a)
    gets the unit world direction from b's hull towards a's nearest one. False where
    the hulls overlap (``n`` then unchanged)."""
    w = np.empty((4, 3))
    scratch = np.empty((8, 3))
    v = n.copy()
    x, y, neg = np.empty(3), np.empty(3), np.empty(3)
    count = 0
    for _ in range(_GJK_ITERATIONS):
        # support of A - B along -v: A's point least along v, B's farthest
        for r in range(3):
            neg[r] = -v[r]
        _support(va, ta, neg, x)
        _support(vb, tb, v, y)
        p0, p1, p2 = x[0] - y[0], x[1] - y[1], x[2] - y[2]
        vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        if count > 0 and vv - (v[0] * p0 + v[1] * p1 + v[2] * p2) <= _GJK_TOLERANCE * vv:
            break  # no support point gets closer: v is (nearly) the nearest point
        dup = False
        for i in range(count):
            if w[i, 0] == p0 and w[i, 1] == p1 and w[i, 2] == p2:
                dup = True
        if dup:
            break
        w[count, 0], w[count, 1], w[count, 2] = p0, p1, p2
        count = _closest(w, count + 1, v, scratch)
        if count == 4 or v[0] * v[0] + v[1] * v[1] + v[2] * v[2] <= 1e-24:
            return False  # the origin is inside: the hulls overlap
    norm = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if not norm > 0.0:
        return False
    for r in range(3):
        n[r] = v[r] / norm
    return True


@numba.njit(cache=True, nogil=True)
def parts_bound(va: np.ndarray, oa: np.ndarray, ra: np.ndarray, ca: np.ndarray,
                ea: np.ndarray, ta: np.ndarray, vb: np.ndarray, ob: np.ndarray,
                rb: np.ndarray, cb: np.ndarray, eb: np.ndarray, tb: np.ndarray,
                cap: float) -> float:
    """A lower bound [m] on the distance between two bodies held by parts (each a
    :class:`Parts`' vertices, offsets, radii, centers and reach; ``ta``, ``tb`` their
    poses, shape (4, 4)), at most ``cap`` [m] (part pairs whose spheres are that far
    apart are not looked at)."""
    ka, kb = ra.shape[0], rb.shape[0]
    wa = np.empty((ka, 3))
    wb = np.empty((kb, 3))
    for i in range(ka):
        for r in range(3):
            wa[i, r] = ta[r, 0] * ca[i, 0] + ta[r, 1] * ca[i, 1] + ta[r, 2] * ca[i, 2] + ta[r, 3]
    for j in range(kb):
        for r in range(3):
            wb[j, r] = tb[r, 0] * cb[j, 0] + tb[r, 1] * cb[j, 1] + tb[r, 2] * cb[j, 2] + tb[r, 3]
    # the spheres' bound for every part pair; the nearest pair first, then the others
    # that could beat it, nearest first (sorting them all costs more than the rest)
    lb = np.empty(ka * kb)
    first = 0
    for i in range(ka):
        for j in range(kb):
            dx, dy, dz = wa[i, 0] - wb[j, 0], wa[i, 1] - wb[j, 1], wa[i, 2] - wb[j, 2]
            lb[i * kb + j] = np.sqrt(dx * dx + dy * dy + dz * dz) - ea[i] - eb[j]
            if lb[i * kb + j] < lb[first]:
                first = i * kb + j
    best = cap
    n = np.empty(3)
    xa, yb = np.empty(3), np.empty(3)
    order = np.empty(ka * kb, np.int64)
    order[0] = first
    count = 1
    for idx in range(ka * kb):
        if idx != first and lb[idx] < cap:
            order[count] = idx
            count += 1
    k = 0
    while k < count:
        if k == 1:
            # the first pair's bound in hand: sort only the pairs that could beat it
            m = 1
            for r in range(1, count):
                if lb[order[r]] < best:
                    order[m] = order[r]
                    m += 1
            count = m
            order[1:count] = order[1:count][np.argsort(lb[order[1:count]])]
            if count == 1:
                break
        idx = order[k]
        k += 1
        if lb[idx] >= best:
            break  # (sorted) every pair left is at least this far apart
        i, j = idx // kb, idx % kb
        pa = va[oa[i]:oa[i + 1]]
        pb = vb[ob[j]:ob[j + 1]]
        slack = ra[i] + rb[j]
        # the separation along the centres' line first: it often rules the pair out
        for r in range(3):
            n[r] = wa[i, r] - wb[j, r]
        norm = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        if norm > 0.0:
            for r in range(3):
                n[r] /= norm
        else:
            n[0], n[1], n[2] = 0.0, 0.0, 1.0
        d = _along(pa, ta, pb, tb, n, xa, yb) - slack
        if d < best and gjk_direction(pa, ta, pb, tb, n):
            d = max(d, _along(pa, ta, pb, tb, n, xa, yb) - slack)
        if d < best:
            best = d
    return best


class PartBounds:
    """Part-hull distance bounds between the bodies of one world (index order of its
    bodies).

    Args:
        parts: one per body (a convex body's: its hull alone).
    """

    def __init__(self, parts: list[Parts]) -> None:
        self._parts = parts

    def split(self, a: int, b: int) -> bool:
        """Whether body ``a`` or ``b`` has more than one part (else their hulls' bound
        is as good)."""
        return self._parts[a].count > 1 or self._parts[b].count > 1

    def bound(self, a: int, ta: np.ndarray, b: int, tb: np.ndarray, *,
              cap: float = np.inf) -> float:
        """A lower bound [m] on the distance between bodies ``a`` and ``b`` at poses
        ``ta``, ``tb`` (shape (4, 4)), at most ``cap`` [m]; 0 or less where some of their
        parts touch."""
        pa, pb = self._parts[a], self._parts[b]
        return float(parts_bound(pa.vertices, pa.offsets, pa.radii, pa.centers, pa.reach,
                                 np.ascontiguousarray(ta, float), pb.vertices, pb.offsets,
                                 pb.radii, pb.centers, pb.reach,
                                 np.ascontiguousarray(tb, float), float(cap)))
