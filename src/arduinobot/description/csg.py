"""The CSG vocabulary :mod:`arduinobot.description.meshgen` models the arduinobot's parts with, on
manifold3d: 2D profiles (circles, stadiums, rounded rectangles), extrusions and lathe
parts along any axis, filleted slabs and boxes. Centimetres, like the parts.
"""

from __future__ import annotations

import math

import numpy as np
from manifold3d import CrossSection, Manifold, OpType

# Segments per full circle.  Multiples of 4 put a vertex on every axis
# extreme, so cylinders and rounded ends hit the envelope faces exactly.
SEG_FINE: int = 96
SEG: int = 64
SEG_SMALL: int = 32
FILLET_STEPS: int = 4
UNION = OpType.Add

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


# ---------------------------------------------------------------- 2D helpers


def circle(center: Vec2, radius: float, segments: int = SEG) -> CrossSection:
    return CrossSection.circle(radius, segments).translate(center)


def stadium(p0: Vec2, p1: Vec2, radius: float, segments: int = SEG) -> CrossSection:
    return CrossSection.batch_hull([circle(p0, radius, segments), circle(p1, radius, segments)])


def rect(lo: Vec2, hi: Vec2) -> CrossSection:
    return CrossSection.square((hi[0] - lo[0], hi[1] - lo[1])).translate(lo)


def rounded_rect(lo: Vec2, hi: Vec2, radius: float, segments: int = SEG_SMALL) -> CrossSection:
    # Hull of corner circles keeps the extents exactly at lo/hi.
    xs = (lo[0] + radius, hi[0] - radius)
    ys = (lo[1] + radius, hi[1] - radius)
    return CrossSection.batch_hull([circle((x, y), radius, segments) for x in xs for y in ys])


# ------------------------------------------------------------ axis mapping

# Cyclic permutations (det +1, so winding survives) taking a shape built
# along local z, with cross-section coordinates (u, v), onto a world axis:
#   z: (u, v) = (x, y)   x: (u, v) = (y, z)   y: (u, v) = (z, x)
_AXIS_MATRIX: dict[str, np.ndarray] = {
    "z": np.eye(3),
    "x": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
    "y": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
}


def along(shape: Manifold, axis: str) -> Manifold:
    m = np.zeros((3, 4))
    m[:, :3] = _AXIS_MATRIX[axis]
    return shape.transform(m)


def extrude(profile: CrossSection, axis: str, lo: float, hi: float) -> Manifold:
    return along(Manifold.extrude(profile, hi - lo).translate((0.0, 0.0, lo)), axis)


def rounded_slab(
    profile: CrossSection,
    axis: str,
    lo: float,
    hi: float,
    fillet: float,
    fillet_lo: bool = True,
    fillet_hi: bool = True,
) -> Manifold:
    """Extrude a *convex* profile with quarter-round fillets on its rims.

    Built as the hull of inset copies of the outline, which is exact for
    convex outlines and far cheaper than a Minkowski sum.
    """
    points: list[tuple[float, float, float]] = []
    for i in range(FILLET_STEPS + 1):
        phi = 0.5 * math.pi * i / FILLET_STEPS
        inset = fillet * (1.0 - math.sin(phi))
        rise = fillet * (1.0 - math.cos(phi))
        layer = profile.offset(-inset) if inset > 1e-9 else profile
        for (u, v) in [tuple(p) for poly in layer.to_polygons() for p in poly]:
            if fillet_lo:
                points.append((u, v, lo + rise))
            if fillet_hi:
                points.append((u, v, hi - rise))
    for (u, v) in [tuple(p) for poly in profile.to_polygons() for p in poly]:
        if not fillet_lo:
            points.append((u, v, lo))
        if not fillet_hi:
            points.append((u, v, hi))
    return along(Manifold.hull_points(points), axis)


def rounded_box(lo: Vec3, hi: Vec3, radius: float, segments: int = SEG_SMALL) -> Manifold:
    corners = [
        Manifold.sphere(radius, segments).translate((x, y, z))
        for x in (lo[0] + radius, hi[0] - radius)
        for y in (lo[1] + radius, hi[1] - radius)
        for z in (lo[2] + radius, hi[2] - radius)
    ]
    return Manifold.batch_hull(corners)


def turned(
    axis: str,
    center: Vec2,
    r_in: float,
    r_out: float,
    lo: float,
    hi: float,
    fillet: float = 0.0,
    segments: int = SEG,
) -> Manifold:
    """A lathe part (disc, boss or ring) about an axis through ``center``.

    ``center`` is given in the axis' cross-section coordinates (see
    ``_AXIS_MATRIX``); the outer rim is rounded by ``fillet``.
    """
    section = rect((r_in, lo), (r_out, hi))
    if fillet > 0.0:
        # Round only the outer rim: a rounded rectangle unioned with the
        # square inner half keeps the bore and the faces flat.
        inner = rect((r_in, lo), (0.5 * (r_in + r_out), hi))
        section = inner + rounded_rect((r_in, lo), (r_out, hi), fillet, SEG_SMALL)
    solid = Manifold.revolve(section, segments)
    return along(solid.translate((center[0], center[1], 0.0)), axis)
