"""Oriented-bounding-box trees: a conservative broad phase in numba, ahead of FCL.

python-fcl costs 10-50 us per call, so a state check that calls it for every pair
cannot meet a 25 us budget. Each body (link mesh or obstacle) gets a binary tree of
OBBs over its triangles; two trees are descended together (separating-axis tests) and
FCL's exact narrow phase runs only for pairs whose leaf boxes overlap, i.e. that are
within a few millimetres of touching. Every box contains its triangles, so a pair the
trees separate cannot collide: the prefilter never hides a collision.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from arduinobot.planner.cache import ArtifactCache, content_key
from arduinobot.planner.collision.table import Bodies, place_carried
from arduinobot.planner.kinematics.chain import Chain, _fk_into


@dataclass(frozen=True)
class ObbTree:
    """Flat arrays of one body's tree; node 0 is the root.

    Attributes:
        center: box centres in the body frame, shape (n, 3) [m].
        axes: box axes as columns, shape (n, 3, 3).
        half: half extents, shape (n, 3) [m].
        left, right: child node indices, -1 for a leaf, shape (n,).
    """

    center: np.ndarray
    axes: np.ndarray
    half: np.ndarray
    left: np.ndarray
    right: np.ndarray


@numba.njit(cache=True, nogil=True)
def _build(tri: np.ndarray, cent: np.ndarray, leaf_size: int, center: np.ndarray,
           axes: np.ndarray, half: np.ndarray, left: np.ndarray, right: np.ndarray) -> int:
    # Top down: fit each node's box to its triangles' vertices (principal axes of their
    # covariance, by LAPACK as numpy's eigh: CAD meshes have many tied projections, and
    # another eigen-solver's signs split the ties differently, measured 4x looser
    # bounds between the fingers), split at the median of the centroids along the
    # longest box axis.
    # Returns the node count; the output arrays hold at least 2 * len(tri) nodes.
    n = len(tri)
    perm = np.arange(n)
    stack = np.empty((2 * n + 2, 4), dtype=np.int64)  # start, end, parent, is_right
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0, n, -1, 0
    top, count = 1, 0
    pts = np.empty((3 * n, 3))
    while top > 0:
        top -= 1
        s, e, parent, is_right = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        node = count
        count += 1
        m = 3 * (e - s)
        for i in range(s, e):
            for v in range(3):
                pts[3 * (i - s) + v] = tri[perm[i], v]
        mean = np.zeros(3)
        for i in range(m):
            mean += pts[i]
        mean /= m
        vecs = np.eye(3)
        if m > 3:
            cov = np.zeros((3, 3))
            for i in range(m):
                d = pts[i] - mean
                for a in range(3):
                    for b in range(3):
                        cov[a, b] += d[a] * d[b]
            cov /= m - 1
            _, vecs = np.linalg.eigh(cov)
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for i in range(m):
            for a in range(3):
                t = ((pts[i, 0] - mean[0]) * vecs[0, a] + (pts[i, 1] - mean[1]) * vecs[1, a]
                     + (pts[i, 2] - mean[2]) * vecs[2, a])
                lo[a] = min(lo[a], t)
                hi[a] = max(hi[a], t)
        c = mean.copy()
        for a in range(3):
            mid = (lo[a] + hi[a]) / 2
            for r in range(3):
                c[r] += vecs[r, a] * mid
        center[node] = c
        axes[node] = vecs
        # a tiny pad keeps boxes of flat triangles from having zero width
        half[node] = (hi - lo) / 2 + 1e-9
        left[node] = -1
        right[node] = -1
        if parent >= 0:
            if is_right:
                right[parent] = node
            else:
                left[parent] = node
        if e - s <= leaf_size:
            continue
        k = np.argmax(half[node])
        proj = np.empty(e - s)
        for i in range(s, e):
            p = cent[perm[i]]
            proj[i - s] = ((p[0] - c[0]) * vecs[0, k] + (p[1] - c[1]) * vecs[1, k]
                           + (p[2] - c[2]) * vecs[2, k])
        order = np.argsort(proj, kind="mergesort")
        perm[s:e] = perm[s:e][order]
        mid = s + (e - s) // 2
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = mid, e, node, 1
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = s, mid, node, 0
        top += 2
    return count


#: bump when the tree builder changes: cached trees of an older builder are never read
TREE_VERSION = "2"


def cached_tree(vertices: np.ndarray, faces: np.ndarray, cache: ArtifactCache | None, *,
                leaf_size: int = 8) -> ObbTree:
    """:func:`build_tree`, from ``cache`` when the same triangles were built before."""
    if cache is None:
        return build_tree(vertices, faces, leaf_size=leaf_size)
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    key = content_key([TREE_VERSION, str(leaf_size), v, f])
    hit = cache.load("obb-tree", key)
    if hit is not None:
        return ObbTree(hit["center"], np.ascontiguousarray(hit["axes"]), hit["half"],
                       hit["left"], hit["right"])
    tree = build_tree(v, f, leaf_size=leaf_size)
    cache.store("obb-tree", key, {"center": tree.center, "axes": tree.axes, "half": tree.half,
                                  "left": tree.left, "right": tree.right})
    return tree


def build_tree(vertices: np.ndarray, faces: np.ndarray, *, leaf_size: int = 8) -> ObbTree:
    """Build a tree over a triangle mesh (vertices shape (v, 3) [m], faces (f, 3))."""
    tri = np.ascontiguousarray(np.asarray(vertices, float)[np.asarray(faces)])  # (f, 3, 3)
    cent = np.ascontiguousarray(tri.mean(axis=1))
    cap = 2 * len(tri) + 1
    center, axes, half = np.empty((cap, 3)), np.empty((cap, 3, 3)), np.empty((cap, 3))
    left, right = np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64)
    n = _build(tri, cent, leaf_size, center, axes, half, left, right)
    return ObbTree(center[:n].copy(), np.ascontiguousarray(axes[:n]), half[:n].copy(),
                   left[:n].copy(), right[:n].copy())


def box_tree(half: np.ndarray) -> ObbTree:
    """A one-node tree: an axis-aligned box of half extents ``half`` about the origin."""
    return ObbTree(np.zeros((1, 3)), np.eye(3)[None], np.asarray(half, float)[None] + 1e-9,
                   np.array([-1]), np.array([-1]))


class Forest(NamedTuple):
    """Every body's tree concatenated, as the numba kernels take it (one argument);
    ``root[b]`` is body b's root node, ``left``/``right`` index the whole forest."""

    center: np.ndarray
    axes: np.ndarray
    half: np.ndarray
    left: np.ndarray
    right: np.ndarray
    root: np.ndarray

    @classmethod
    def of(cls, trees: list[ObbTree]) -> Forest:
        offs = np.cumsum([0] + [len(t.center) for t in trees])

        def shift(a: np.ndarray, o: int) -> np.ndarray:
            return np.where(a >= 0, a + o, -1)

        return cls(np.concatenate([t.center for t in trees]),
                   np.ascontiguousarray(np.concatenate([t.axes for t in trees])),
                   np.concatenate([t.half for t in trees]),
                   np.concatenate([shift(t.left, o) for t, o in zip(trees, offs)]),
                   np.concatenate([shift(t.right, o) for t, o in zip(trees, offs)]),
                   offs[:-1].astype(np.int64))


@numba.njit(cache=True, nogil=True, inline="always")
def in_box_frame(ra: np.ndarray, rb: np.ndarray, d0: float, d1: float, d2: float,
                 r: np.ndarray, ar: np.ndarray, t: np.ndarray) -> None:
    """Box b in box a's axes, as the separating-axis tests use it: the centre offset
    (d0, d1, d2) in a's axes into ``t`` (3,), b's axes in a's into ``r`` (3, 3) and their
    magnitudes, padded against rounding, into ``ar`` (3, 3)."""
    for i in range(3):
        t[i] = d0 * ra[0, i] + d1 * ra[1, i] + d2 * ra[2, i]
        for j in range(3):
            v = ra[0, i] * rb[0, j] + ra[1, i] * rb[1, j] + ra[2, i] * rb[2, j]
            r[i, j] = v
            ar[i, j] = abs(v) + 1e-12


@numba.njit(cache=True, nogil=True, inline="always")
def _sep(ra: np.ndarray, ca: np.ndarray, ha: np.ndarray, rb: np.ndarray, cb: np.ndarray,
         hb: np.ndarray, pad: float, r: np.ndarray, ar: np.ndarray, t: np.ndarray) -> bool:
    # Gottschalk's 15-axis separating-axis test; boxes inflated by pad in total.
    # r, ar (3, 3) and t (3,) are scratch: numba heap-allocates arrays, too slow here.
    in_box_frame(ra, rb, cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2], r, ar, t)
    a0, a1, a2 = ha[0] + pad, ha[1] + pad, ha[2] + pad
    b0, b1, b2 = hb[0], hb[1], hb[2]
    for i in range(3):
        ai = a0 if i == 0 else (a1 if i == 1 else a2)
        if abs(t[i]) > ai + b0 * ar[i, 0] + b1 * ar[i, 1] + b2 * ar[i, 2]:
            return True
    for j in range(3):
        bj = b0 if j == 0 else (b1 if j == 1 else b2)
        if abs(t[0] * r[0, j] + t[1] * r[1, j] + t[2] * r[2, j]) > \
                a0 * ar[0, j] + a1 * ar[1, j] + a2 * ar[2, j] + bj:
            return True
    ha_ = (a0, a1, a2)
    hb_ = (b0, b1, b2)
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            lhs = abs(t[i2] * r[i1, j] - t[i1] * r[i2, j])
            rhs = (ha_[i1] * ar[i2, j] + ha_[i2] * ar[i1, j]
                   + hb_[j1] * ar[i, j2] + hb_[j2] * ar[i, j1])
            if lhs > rhs:
                return True
    return False


@numba.njit(cache=True, nogil=True)
def box_in_frame(rel_r: np.ndarray, rel_t: np.ndarray, center: np.ndarray, axes: np.ndarray,
                 rb: np.ndarray, cb: np.ndarray) -> None:
    """Write a box's axes (3, 3) and centre (3,), moved by (rel_r, rel_t), into rb, cb."""
    for i in range(3):
        cb[i] = rel_t[i]
        for k in range(3):
            cb[i] += rel_r[i, k] * center[k]
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += rel_r[i, k] * axes[k, j]
            rb[i, j] = acc


@numba.njit(cache=True, nogil=True)
def relative_pose(ta: np.ndarray, tb: np.ndarray, rel_r: np.ndarray, rel_t: np.ndarray) -> None:
    """Write inv(ta) @ tb into ``rel_r`` (3, 3) and ``rel_t`` (3,): b's pose in a's frame."""
    for i in range(3):
        rel_t[i] = 0.0
        for k in range(3):
            rel_t[i] += ta[k, i] * (tb[k, 3] - ta[k, 3])
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += ta[k, i] * tb[k, j]
            rel_r[i, j] = acc


@numba.njit(cache=True, nogil=True)
def trees_overlap(ta: np.ndarray, a: int, tb: np.ndarray, b: int, center: np.ndarray,
                  axes: np.ndarray, half: np.ndarray, left: np.ndarray, right: np.ndarray,
                  pad: float, stack: np.ndarray, scratch: np.ndarray) -> bool:
    """True if some leaf box of tree ``a`` (pose ``ta``) overlaps one of ``b`` (pose
    ``tb``); the trees are a :class:`Forest`'s arrays (its root nodes ``a``, ``b``).

    ``scratch`` is a work buffer, shape (8, 3, 3).
    """
    # Work in a's frame: b's boxes are moved by rel = inv(ta) @ tb.
    rel_r = scratch[0]
    rel_t = scratch[1, 0]
    rb = scratch[2]
    cb = scratch[1, 1]
    relative_pose(ta, tb, rel_r, rel_t)
    # quick reject on the roots' bounding spheres
    ca, cr = center[a], center[b]
    dd = 0.0
    for i in range(3):
        pa = ta[i, 3] + ta[i, 0] * ca[0] + ta[i, 1] * ca[1] + ta[i, 2] * ca[2]
        pb = tb[i, 3] + tb[i, 0] * cr[0] + tb[i, 1] * cr[1] + tb[i, 2] * cr[2]
        dd += (pa - pb) ** 2
    ra_ = np.sqrt(half[a, 0] ** 2 + half[a, 1] ** 2 + half[a, 2] ** 2)
    rb_ = np.sqrt(half[b, 0] ** 2 + half[b, 1] ** 2 + half[b, 2] ** 2)
    if np.sqrt(dd) > ra_ + rb_ + pad:
        return False
    stack[0, 0] = a
    stack[0, 1] = b
    top = 1
    while top > 0:
        top -= 1
        na, nb = stack[top, 0], stack[top, 1]
        box_in_frame(rel_r, rel_t, center[nb], axes[nb], rb, cb)
        if _sep(axes[na], center[na], half[na], rb, cb, half[nb], pad, scratch[3],
                scratch[4], scratch[1, 2]):
            continue
        la, lb = left[na], left[nb]
        if la < 0 and lb < 0:
            return True
        if top + 2 > stack.shape[0]:
            return True  # conservative if the stack is exhausted
        # descend the larger box first so both trees shrink evenly
        va = half[na, 0] * half[na, 1] * half[na, 2]
        vb = half[nb, 0] * half[nb, 1] * half[nb, 2]
        if lb < 0 or (la >= 0 and va >= vb):
            stack[top, 0], stack[top, 1] = la, nb
            stack[top + 1, 0], stack[top + 1, 1] = right[na], nb
        else:
            stack[top, 0], stack[top, 1] = na, lb
            stack[top + 1, 0], stack[top + 1, 1] = na, right[nb]
        top += 2
    return False


@numba.njit(cache=True, nogil=True)
def pair_candidates(poses: np.ndarray, bodies: Bodies, pairs: np.ndarray, forest: Forest,
                    pad: float, stack: np.ndarray, out: np.ndarray) -> int:
    """Mark pairs ``pairs`` (n_pairs, 2) of ``bodies`` whose trees overlap for one state
    (pose slots ``poses`` (n_slots, 4, 4): the links', then the carried objects').

    Returns the number of marked pairs; ``out`` shape (n_pairs,) gets 1/0.
    """
    n = 0
    scratch = np.empty((8, 3, 3))
    # unpacked once: taking an array out of a tuple costs a reference count
    frame, pose = bodies.frame, bodies.pose
    center, axes, half, left, right, root = forest
    for p in range(pairs.shape[0]):
        a, b = pairs[p, 0], pairs[p, 1]
        ta = poses[frame[a]] if frame[a] >= 0 else pose[a]
        tb = poses[frame[b]] if frame[b] >= 0 else pose[b]
        hit = trees_overlap(ta, root[a], tb, root[b], center, axes, half, left, right, pad,
                            stack, scratch)
        out[p] = 1 if hit else 0
        n += 1 if hit else 0
    return n


@numba.njit(cache=True, nogil=True)
def state_candidates(q: np.ndarray, chain: Chain, bodies: Bodies, pairs: np.ndarray,
                     forest: Forest, pad: float, poses: np.ndarray, stack: np.ndarray,
                     out: np.ndarray) -> int:
    """:func:`pair_candidates` at state ``q`` (dof,), its pose slots computed into
    ``poses`` (n_slots, 4, 4) on the way (one call from Python, not two: a state check
    is ~20 us, and each crossing costs one or two)."""
    parent, origin, jtype, axis, src, scale, offset = chain
    _fk_into(q, parent, origin, jtype, axis, src, scale, offset, poses)
    place_carried(bodies.frame, bodies.link, bodies.pose, bodies.carried, poses)
    return pair_candidates(poses, bodies, pairs, forest, pad, stack, out)
