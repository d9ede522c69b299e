"""Convex hulls: a cheap lower bound on a pair's distance where the OBB trees give none.

A body lies inside its convex hull, so the hulls' distance never exceeds the bodies'.
FCL's GJK on two hulls costs about 10 us against 300-2000 us for the exact distance
between two CAD meshes (measured on the course model's links, 1,000-2,500 hull
vertices). GJK only supplies a direction ``n`` here; the bound is the separation of the
two bodies along it, ``min_A n.x - max_B n.y``, which is below the distance for *any*
unit ``n`` (for x in A, y in B: ``|x - y| >= n.(x - y)``). So the bound holds however
early GJK stopped: FCL's libccd GJK overestimates distances by up to 0.5 mm at 0.85 mm
on these hulls (measured), and that error can only make ``n`` less good, never the
bound wrong.

Near a concave body (a finger in the base's hollow) the hulls touch while the meshes do
not: the bound is then 0 or less, and the caller asks FCL for the exact distance.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import NamedTuple

import fcl
import numba
import numpy as np
import trimesh
from scipy.spatial import ConvexHull, QhullError

from arduinobot.planner.cache import ArtifactCache, content_key
from arduinobot.scene.obstacles import Obstacle

_log = logging.getLogger(__name__)

#: bump when the hull builder changes: cached hulls of an older builder are never read
HULL_VERSION = "1"
# [m] qhull keeps every input point within its precision of the facets it returns (at
# most 5e-14 m outside on the course and shipped links, measured): the bound gives that
# much away, and this slack for the rounding at sharp corners
_SLACK = 1e-9
# [m] a hull leaving points farther out than this is not trusted (the box stands in)
_MAX_OUTSIDE = 1e-10


@dataclass(frozen=True, eq=False)
class Hull:
    """A convex stand-in for one body, in the body's frame.

    Attributes:
        vertices: shape (m, 3) [m]; the body lies within ``radius`` of their convex hull.
        radius: [m] (a sphere obstacle: its centre and radius; a mesh: qhull's
            rounding; 0 for a box or cylinder).
        geometry: the same convex set for FCL's GJK (it only steers the bound).
    """

    vertices: np.ndarray
    radius: float
    geometry: fcl.CollisionGeometry


def _convex(vertices: np.ndarray, faces: np.ndarray) -> fcl.Convex:
    flat = np.hstack([np.full((len(faces), 1), 3), faces]).ravel().astype(np.int32)
    return fcl.Convex(np.ascontiguousarray(vertices, float), len(faces), flat)


def _box(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    box = trimesh.creation.box(bounds=np.array([v.min(axis=0), v.max(axis=0)]))
    return np.asarray(box.vertices, float), np.asarray(box.faces, np.int64)


@numba.njit(cache=True, nogil=True)
def _outside(points: np.ndarray, planes: np.ndarray) -> float:
    # how far [m] the farthest point lies outside any facet's plane (n.x + d, n unit);
    # every point against every facet, without a points x facets array (~1 GB at 50k)
    worst = -np.inf
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for f in range(planes.shape[0]):
            worst = max(worst, planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z
                        + planes[f, 3])
    return worst


def _qhull(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    # hull vertices, triangles, and how far [m] any point lies outside a facet's plane;
    # the axis-aligned box (and 0) where qhull refuses the input (flat or too few
    # points): looser, still around the whole body. No joggling (QJ): that may leave
    # out an extreme point.
    try:
        hull = ConvexHull(v, qhull_options="Qt")
    except QhullError:
        _log.info("no convex hull for a %d-vertex mesh (flat?): using its box", len(v))
        return (*_box(v), 0.0)
    outside = _outside(v, np.ascontiguousarray(hull.equations))
    if outside > _MAX_OUTSIDE:
        _log.info("a convex hull leaves points %.1e m outside: using the box", outside)
        return (*_box(v), 0.0)
    idx = np.unique(hull.simplices)
    remap = np.full(len(v), -1, np.int64)
    remap[idx] = np.arange(len(idx))
    return np.ascontiguousarray(v[idx]), remap[hull.simplices], max(outside, 0.0)


def mesh_hull(vertices: np.ndarray, cache: ArtifactCache | None = None) -> Hull:
    """The convex hull of a mesh's vertices (shape (v, 3) [m]), from ``cache`` when the
    same vertices were hulled before."""
    v = np.ascontiguousarray(vertices, float)
    key = content_key([HULL_VERSION, v]) if cache is not None else ""
    hit = cache.load("convex-hull", key) if cache is not None else None
    if hit is not None:
        hv, hf, outside = hit["vertices"], hit["faces"], float(hit["outside"][0])
    else:
        hv, hf, outside = _qhull(v)
        if cache is not None:
            cache.store("convex-hull", key, {"vertices": hv, "faces": hf,
                                             "outside": np.array([outside])})
    return Hull(hv, _SLACK + outside, _convex(hv, hf))


def primitive_hull(o: Obstacle) -> Hull:
    """A box, sphere or cylinder obstacle as its own convex set (a cylinder's
    circumscribed prism for the support)."""
    hull = o.geometry.hull_points()
    if hull is None:
        raise ValueError(f"obstacle '{o.id}' is a {o.shape}, not a primitive: use mesh_hull")
    points, radius = hull
    return Hull(points, radius, o.geometry.collision_geometry())


@numba.njit(cache=True, nogil=True)
def separation(va: np.ndarray, ta: np.ndarray, vb: np.ndarray, tb: np.ndarray,
               n: np.ndarray) -> float:
    """``min n.x`` over ``va`` placed by ``ta`` less ``max n.y`` over ``vb`` placed by
    ``tb`` (vertices shape (m, 3), poses (4, 4), ``n`` a unit world direction): a lower
    bound [m] on the distance between any sets held by the two vertex hulls."""
    return _along(va, ta, vb, tb, n, np.empty(3), np.empty(3))


@numba.njit(cache=True, nogil=True)
def _along(va: np.ndarray, ta: np.ndarray, vb: np.ndarray, tb: np.ndarray, n: np.ndarray,
           xa: np.ndarray, yb: np.ndarray) -> float:
    # separation(), with the extreme points that make it (world frame) in xa, yb
    ma = np.empty(3)
    mb = np.empty(3)
    for i in range(3):  # n in each body's frame
        ma[i] = ta[0, i] * n[0] + ta[1, i] * n[1] + ta[2, i] * n[2]
        mb[i] = tb[0, i] * n[0] + tb[1, i] * n[1] + tb[2, i] * n[2]
    ia, ib = 0, 0
    lo, hi = np.inf, -np.inf
    for i in range(va.shape[0]):
        x = va[i, 0] * ma[0] + va[i, 1] * ma[1] + va[i, 2] * ma[2]
        if x < lo:
            lo, ia = x, i
    for i in range(vb.shape[0]):
        y = vb[i, 0] * mb[0] + vb[i, 1] * mb[1] + vb[i, 2] * mb[2]
        if y > hi:
            hi, ib = y, i
    for r in range(3):
        xa[r] = ta[r, 0] * va[ia, 0] + ta[r, 1] * va[ia, 1] + ta[r, 2] * va[ia, 2] + ta[r, 3]
        yb[r] = tb[r, 0] * vb[ib, 0] + tb[r, 1] * vb[ib, 1] + tb[r, 2] * vb[ib, 2] + tb[r, 3]
    return (lo + n[0] * ta[0, 3] + n[1] * ta[1, 3] + n[2] * ta[2, 3]
            - hi - n[0] * tb[0, 3] - n[1] * tb[1, 3] - n[2] * tb[2, 3])


class HullPack(NamedTuple):
    """Every body's hull packed for compiled code (one argument): body ``i``'s vertices
    are ``vertices[offsets[i]:offsets[i + 1]]`` (shape (v, 3), its frame), within
    ``radii[i]`` [m] of which it lies."""

    vertices: np.ndarray
    offsets: np.ndarray
    radii: np.ndarray


@numba.njit(cache=True, nogil=True)
def warm_bound(vertices: np.ndarray, offsets: np.ndarray, radii: np.ndarray, a: int,
               ta: np.ndarray, b: int, tb: np.ndarray, n: np.ndarray) -> float:
    """The hull bound [m] of bodies ``a`` and ``b`` (poses ``ta``, ``tb``) from a given
    unit world direction ``n`` (e.g. the last one GJK found for the pair): the better of
    the separation along ``n`` and along the line between the extreme points it picks
    (which ``n`` then becomes). Sound for any ``n``, close to GJK's while the bodies have
    hardly moved, in a few microseconds and without leaving compiled code.
    ``vertices``, ``offsets``, ``radii``: a :class:`HullPack`'s (the caller unpacks it
    once: this runs per step)."""
    va = vertices[offsets[a]:offsets[a + 1]]
    vb = vertices[offsets[b]:offsets[b + 1]]
    xa, yb, m = np.empty(3), np.empty(3), np.empty(3)
    d = _along(va, ta, vb, tb, n, xa, yb)
    for r in range(3):
        m[r] = xa[r] - yb[r]
    norm = np.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
    if norm > 0.0:
        for r in range(3):
            m[r] /= norm
        e = _along(va, ta, vb, tb, m, xa, yb)
        if e > d:
            d = e
            n[:] = m
    return d - radii[a] - radii[b]


class HullBounds:
    """Hull distance bounds between the bodies of one world (index order of its bodies).

    Args:
        hulls: one per body.
        static_poses: shape (n_bodies, 4, 4), the pose of each body that never moves.

    Attributes:
        pack: every hull packed for compiled code (:class:`HullPack`).
    """

    def __init__(self, hulls: list[Hull], static_poses: np.ndarray) -> None:
        self._hulls = hulls
        self._objs = [fcl.CollisionObject(h.geometry, fcl.Transform(p[:3, :3], p[:3, 3]))
                      for h, p in zip(hulls, static_poses)]
        self._request = fcl.DistanceRequest(enable_nearest_points=True)
        self.pack = HullPack(
            np.ascontiguousarray(np.concatenate([h.vertices for h in hulls])
                                 if hulls else np.zeros((0, 3)), dtype=float),
            np.cumsum([0] + [len(h.vertices) for h in hulls]).astype(np.int64),
            np.array([h.radius for h in hulls], float))

    def bound(self, a: int, ta: np.ndarray, b: int, tb: np.ndarray, *,
              direction: np.ndarray | None = None) -> float:
        """A lower bound [m] on the distance between bodies ``a`` and ``b`` at poses
        ``ta``, ``tb`` (shape (4, 4)); 0 or less where their hulls touch. ``direction``
        (shape (3,)), if given, gets the unit direction the bound was taken along (for
        :func:`warm_bound`), where the hulls are apart."""
        oa, ob = self._objs[a], self._objs[b]
        for o, t in ((oa, ta), (ob, tb)):
            o.setRotation(t[:3, :3])
            o.setTranslation(t[:3, 3])
        res = fcl.DistanceResult()
        fcl.distance(oa, ob, self._request, res)
        n = np.asarray(res.nearest_points[0], float) - np.asarray(res.nearest_points[1], float)
        norm = float(np.sqrt(n @ n))
        if not norm > 0.0:
            return 0.0  # touching (or penetrating): no direction, no bound
        if direction is not None:
            direction[:] = n / norm
        ha, hb = self._hulls[a], self._hulls[b]
        return float(separation(ha.vertices, np.ascontiguousarray(ta), hb.vertices,
                                np.ascontiguousarray(tb), n / norm)) - ha.radius - hb.radius
