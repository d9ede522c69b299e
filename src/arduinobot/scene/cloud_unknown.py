"""Space the camera did not see, stated: ``unknown: "occupied"`` fills its shadow.

Every peer treats space a depth camera could not see as free. With ``unknown:
"occupied"`` and the camera's pose and field of view, the cells of the camera's frustum
(``hfov``, ``vfov`` [rad], out to ``range`` [m] along its view axis) that are not in front
of a measured point count as obstacles: behind a measured surface, and along rays that
returned nothing (no return is not proof of free space).

The camera looks along its +x axis (REP 103: x forward, y left, z up; a link such as the
course's ``rgb_camera`` is posed so). Points are projected as a pinhole image onto
``x = 1`` (``u = y / x``, ``v = z / x``); each pixel keeps its nearest measured depth
``x``. A cell of the frustum is shadow when its centre's depth plus its half diagonal
reaches beyond the nearest depth of the pixels its box covers (a minimum over a window as
wide as the box's image), so a cell partly behind a surface counts, whole.

The shadow is its own grid (:func:`shadow_cells`): as fine as the cloud's where the
frustum allows, coarser where it would exceed :data:`MAX_SHADOW_CELLS` (a 1 rad by 1 rad
frustum 2 m deep holds 3.2 m^3: 200,000 cells of 2.5 cm).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.cloud import Cells

#: Most cells of one camera's shadow grid (its cell grows to keep under it).
MAX_SHADOW_CELLS = 200_000
#: Most cells of the frustum's bounding box tested (a camera tilted off the world's axes
#: has a box up to ~3x the frustum).
MAX_SHADOW_CANDIDATES = 2_000_000
#: [m] the longest range a camera may state
MAX_RANGE = 10.0
# the image's pixel: this fraction of a shadow cell at the range
_PIXEL = 0.5
# the widest window [pixels] a cell's box is taken over (nearer cells: this one's)
_MAX_WINDOW = 24


@dataclass(frozen=True)
class Camera:
    """A camera's pose in the world and its frustum.

    Attributes:
        pose: shape (4, 4), world from camera (+x forward).
        hfov, vfov: full horizontal and vertical field of view [rad], in (0, pi).
        range: how far it sees along +x [m].
    """

    pose: np.ndarray
    hfov: float
    vfov: float
    range: float

    @classmethod
    def from_mapping(cls, data: object, pose: np.ndarray, *, where: str = "camera") -> Camera:
        """``{"hfov", "vfov", "range"}`` of a camera at ``pose`` (resolved by the caller
        from the request's ``link`` or ``xyz``/``rpy``)."""
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object {link or xyz/rpy, hfov, vfov, range}",
                                 field=where)
        out = {}
        for key, hi in (("hfov", math.pi), ("vfov", math.pi), ("range", MAX_RANGE)):
            v = data.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or not 0 < v < hi or (key == "range" and v > hi):
                raise InvalidRequest(f"{v!r} must be a number in (0, {hi:.4g})"
                                     f" [{'m' if key == 'range' else 'rad'}]",
                                     field=f"{where}.{key}")
            out[key] = float(v)
        return cls(np.asarray(pose, float), out["hfov"], out["vfov"], out["range"])

    def volume(self) -> float:
        """The frustum's volume [m^3]."""
        return 4.0 / 3.0 * self.range ** 3 * math.tan(self.hfov / 2) * math.tan(self.vfov / 2)


def shadow_resolution(camera: Camera, resolution: float) -> float:
    """[m] the shadow grid's cell: the cloud's, or coarser to stay under the cap."""
    return max(resolution, (camera.volume() / MAX_SHADOW_CELLS) ** (1 / 3))


def _depth_image(local: np.ndarray, tu: float, tv: float, pitch: float
                 ) -> tuple[np.ndarray, int, int]:
    w = max(1, math.ceil(2 * tu / pitch))
    h = max(1, math.ceil(2 * tv / pitch))
    img = np.zeros(h * w)  # no return: unknown from the camera on
    x = local[:, 0]
    ok = x > 1e-9
    u, v, x = local[ok, 1] / x[ok], local[ok, 2] / x[ok], x[ok]
    inside = (np.abs(u) <= tu) & (np.abs(v) <= tv)
    col = np.minimum(((u[inside] + tu) / pitch).astype(np.int64), w - 1)
    row = np.minimum(((v[inside] + tv) / pitch).astype(np.int64), h - 1)
    pix = row * w + col
    depth = np.full(h * w, np.inf)
    np.minimum.at(depth, pix, x[inside])
    seen = np.isfinite(depth)
    img[seen] = depth[seen]
    return img.reshape(h, w), w, h


def shadow_cells(points: np.ndarray, camera: Camera, resolution: float, *,
                 where: str = "camera") -> Cells:
    """The frustum's cells not in front of a measured point (world ``points`` shape
    (n, 3) [m], every one measured, the robot's too: it hides what is behind it), on a
    grid of :func:`shadow_resolution`.

    Raises:
        InvalidRequest: the frustum's bounding box holds more than
            :data:`MAX_SHADOW_CANDIDATES` cells (``camera.range``).
    """
    from scipy.ndimage import minimum_filter

    res = shadow_resolution(camera, resolution)
    rot, org = camera.pose[:3, :3], camera.pose[:3, 3]
    tu, tv = math.tan(camera.hfov / 2), math.tan(camera.vfov / 2)
    pitch = _PIXEL * res / camera.range
    img, w, h = _depth_image((points - org) @ rot, tu, tv, pitch)
    # the frustum's corners in the world: its bounding box's cells are the candidates
    far = np.array([[camera.range, su * tu * camera.range, sv * tv * camera.range]
                    for su in (-1, 1) for sv in (-1, 1)])
    corners = np.vstack([np.zeros((1, 3)), far]) @ rot.T + org
    lo = np.floor(corners.min(axis=0) / res).astype(np.int64)
    hi = np.floor(corners.max(axis=0) / res).astype(np.int64)
    span = hi - lo + 1
    if int(np.prod(span)) > MAX_SHADOW_CANDIDATES:
        raise InvalidRequest(f"the frustum's box holds {int(np.prod(span))} cells of "
                             f"{res:.3g} m, more than {MAX_SHADOW_CANDIDATES}: a shorter "
                             "range", field=f"{where}.range",
                             details={"limit": MAX_SHADOW_CANDIDATES})
    grid = np.stack(np.meshgrid(*(np.arange(a, b + 1) for a, b in zip(lo, hi)),
                                indexing="ij"), axis=-1).reshape(-1, 3)
    local = ((grid + 0.5) * res - org) @ rot
    half_diag = res * math.sqrt(3) / 2
    x = local[:, 0]
    # a cell counts if any part of its box may be in the frustum
    near = x + half_diag
    ok = (near > 0) & (x - half_diag <= camera.range)
    xs = np.maximum(x, half_diag)  # a box around the camera: its widest image
    reach = half_diag / xs  # the box's half width on the image plane (at worst)
    u, v = local[:, 1] / xs, local[:, 2] / xs
    ok &= (np.abs(u) <= tu + reach) & (np.abs(v) <= tv + reach)
    idx = np.flatnonzero(ok)
    col = np.clip(((u[idx] + tu) / pitch).astype(np.int64), 0, w - 1)
    row = np.clip(((v[idx] + tv) / pitch).astype(np.int64), 0, h - 1)
    window = np.minimum(np.ceil(reach[idx] / pitch).astype(np.int64), _MAX_WINDOW)
    nearest = np.empty(len(idx))
    for k in np.unique(window):
        sel = window == k
        m = minimum_filter(img, size=2 * int(k) + 1, mode="nearest") if k > 0 else img
        nearest[sel] = m[row[sel], col[sel]]
    # a box near the camera wider than the widest window: unknown (cannot be shown free)
    wide = reach[idx] / pitch > _MAX_WINDOW
    shadow = wide | (near[idx] > nearest)
    return Cells(np.ascontiguousarray(grid[idx[shadow]]), float(res))
