"""GJK on two convex vertex sets, in numba: the direction between their nearest points.

Only a direction is wanted (:mod:`.parts` takes the bound as the separation along it,
sound for any direction), so an early or inexact stop can only loosen a bound. The
nearest point of each simplex is found by trying every face holding the newest
support point (Johnson's sub-algorithm by enumeration: at most 8 faces of 4 points).
"""

from __future__ import annotations

import numba
import numpy as np

# GJK: iterations at most, and the relative progress below which it stops
_GJK_ITERATIONS = 32
_GJK_TOLERANCE = 1e-6


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
