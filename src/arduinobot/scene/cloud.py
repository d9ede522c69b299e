"""Point clouds from a depth camera: decoded, bounded and kept as occupied cells.

A cloud comes as ``{"format": "xyz32" | "xyz64", "data": base64}``: little-endian
float32 (or float64) x, y, z per point, in the frame its pose names. Everything here runs
on untrusted bytes, so each check comes before the work it bounds: the base64 text's
length, the decoded size (:data:`MAX_CLOUD_BYTES`), the record size (a truncated point
is refused), the point count (:data:`MAX_CLOUD_POINTS`). Non-finite points (a depth
camera's holes are NaN) are dropped and counted, not refused, unless none is left.

The kept points become the occupied cells of a grid of ``resolution`` [m] aligned with
the world's axes (:func:`voxelise`): a cell is an axis-aligned box, so a clearance proven
to the box holds for every point measured inside it. Each refusal is an
:class:`~arduinobot.contract.errors.InvalidRequest` naming the field (``add[0].points``).
"""

from __future__ import annotations

import base64
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from arduinobot.contract.caps import MAX_CLOUD_BYTES, MAX_CLOUD_POINTS
from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.inline import base64_cap, decode_inline

CloudFormat = Literal["xyz32", "xyz64"]
FORMATS: dict[str, np.dtype] = {"xyz32": np.dtype("<f4"), "xyz64": np.dtype("<f8")}
#: Longest base64 text of a cloud [characters]: :data:`MAX_CLOUD_BYTES` encoded.
MAX_CLOUD_BASE64 = base64_cap(MAX_CLOUD_BYTES)
#: The cell edge [m] a cloud may ask for: finer costs memory, coarser hides the scene.
RESOLUTION_RANGE = (0.002, 0.1)
#: Most cells along one axis of a cloud's grid (its extent over its resolution): cell
#: indices are packed into one int64 key, 21 bits an axis.
MAX_GRID_CELLS = 2**20


@dataclass(frozen=True)
class DecodedPoints:
    """A cloud's finite points and how many were dropped.

    Attributes:
        points: shape (n, 3) [m], float64, in the cloud's frame.
        dropped: points with a NaN or infinite coordinate, dropped.
    """

    points: np.ndarray
    dropped: int


def decode_points(spec: object, *, field: str = "points") -> DecodedPoints:
    """Decode and bound ``{"format": "xyz32" | "xyz64", "data": base64}``.

    Raises:
        InvalidRequest: not an object, an unknown format, not base64, over
            :data:`MAX_CLOUD_BYTES` or :data:`MAX_CLOUD_POINTS` (``details.limit``), a
            byte count that is not whole points (truncated), or no finite point.
    """
    if not isinstance(spec, Mapping):
        raise InvalidRequest("must be an object {format, data}", field=field)
    extra = sorted(set(spec) - {"format", "data"})
    if extra:
        raise InvalidRequest(f"unknown field(s) {', '.join(extra)}", field=field)
    fmt = spec.get("format")
    if not isinstance(fmt, str) or fmt not in FORMATS:
        raise InvalidRequest(f"{fmt!r} is not one of {', '.join(FORMATS)}",
                             field=f"{field}.format")
    raw = decode_inline(spec.get("data"), cap=MAX_CLOUD_BYTES, noun="cloud",
                        contents="the points' bytes", field=f"{field}.data")
    return points_of_bytes(raw, FORMATS[fmt], field=field)


def points_of_bytes(raw: bytes, dtype: np.dtype, *, field: str = "points") -> DecodedPoints:
    """Points from packed x, y, z records of ``dtype`` (bounded as :func:`decode_points`)."""
    if len(raw) > MAX_CLOUD_BYTES:
        raise InvalidRequest(f"a cloud of {len(raw)} bytes, more than {MAX_CLOUD_BYTES}",
                             field=f"{field}.data", details={"limit": MAX_CLOUD_BYTES})
    record = 3 * dtype.itemsize
    if len(raw) % record:
        raise InvalidRequest(f"{len(raw)} bytes is not a whole number of {record}-byte "
                             "points (truncated?)", field=f"{field}.data")
    n = len(raw) // record
    if n > MAX_CLOUD_POINTS:
        raise InvalidRequest(f"{n} points, more than {MAX_CLOUD_POINTS}",
                             field=f"{field}.data", details={"limit": MAX_CLOUD_POINTS})
    pts = np.frombuffer(raw, dtype=dtype).reshape(n, 3)
    return finite_points(pts, field=field)


def finite_points(points: Any, *, field: str = "points") -> DecodedPoints:
    """``points`` (shape (n, 3)) as float64 without its non-finite rows, counted.

    Raises:
        InvalidRequest: not shape (n, 3), over :data:`MAX_CLOUD_POINTS`, or no finite
            point (``details.dropped``).
    """
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InvalidRequest(f"shape {pts.shape} is not (n, 3)", field=field)
    if len(pts) > MAX_CLOUD_POINTS:
        raise InvalidRequest(f"{len(pts)} points, more than {MAX_CLOUD_POINTS}",
                             field=field, details={"limit": MAX_CLOUD_POINTS})
    pts = pts.astype(np.float64, copy=False)
    finite = np.isfinite(pts).all(axis=1)
    kept = pts[finite] if not finite.all() else pts
    dropped = len(pts) - len(kept)
    if len(kept) == 0:
        raise InvalidRequest(f"no finite point ({dropped} dropped as NaN or infinite)",
                             field=field, details={"dropped": dropped})
    return DecodedPoints(np.ascontiguousarray(kept), dropped)


def encode_points(points: Any, fmt: CloudFormat = "xyz32") -> dict[str, str]:
    """The wire form of ``points`` (shape (n, 3) [m]): what :func:`decode_points` reads."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=FORMATS[fmt]).reshape(-1, 3))
    return {"format": fmt, "data": base64.b64encode(pts.tobytes()).decode("ascii")}


def check_resolution(value: object, *, field: str = "resolution") -> float:
    """A cell edge [m] within :data:`RESOLUTION_RANGE`."""
    lo, hi = RESOLUTION_RANGE
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or not lo <= value <= hi:
        raise InvalidRequest(f"{value!r} must be a cell edge from {lo} to {hi} [m]",
                             field=field)
    return float(value)


@dataclass(frozen=True, eq=False)
class Cells:
    """Occupied cells of a grid aligned with the world's axes.

    Cell ``(i, j, k)`` is the box ``[i, i+1] x [j, j+1] x [k, k+1]`` times ``resolution``.

    Attributes:
        index: the cells' integer coordinates, shape (n, 3) int64, unique, sorted.
        resolution: the cell edge [m].
    """

    index: np.ndarray
    resolution: float

    def __len__(self) -> int:
        return len(self.index)

    @property
    def centers(self) -> np.ndarray:
        """Each cell's centre in the world [m], shape (n, 3)."""
        return (self.index + 0.5) * self.resolution

    def keep(self, mask: np.ndarray) -> Cells:
        """The cells where ``mask`` (shape (n,) bool) is true."""
        return Cells(self.index[mask], self.resolution)

    def union(self, other: Cells) -> Cells:
        """Both sets of cells (the same resolution) without repeats."""
        if other.resolution != self.resolution:
            raise ValueError("cells of different resolutions")
        return Cells(np.unique(np.vstack([self.index, other.index]), axis=0),
                     self.resolution)


def voxelise(points: np.ndarray, resolution: float, *, field: str = "points"
             ) -> tuple[Cells, np.ndarray]:
    """The occupied cells of world points ``points`` (shape (n, 3) [m], finite), and
    each point's cell (shape (n,), indices into the cells).

    Raises:
        InvalidRequest: the cloud spans more than :data:`MAX_GRID_CELLS` cells along an
            axis (``details.limit``).
    """
    idx = np.floor(points * (1.0 / resolution)).astype(np.int64)
    lo = idx.min(axis=0)
    span = idx.max(axis=0) - lo + 1
    if int(span.max()) > MAX_GRID_CELLS:
        raise InvalidRequest(f"spans {int(span.max())} cells of {resolution} m, more than "
                             f"{MAX_GRID_CELLS}", field=field,
                             details={"limit": MAX_GRID_CELLS})
    rel = idx - lo
    # one int64 key per cell (21 bits an axis): np.unique on keys, not rows, is ~10x faster
    key = (rel[:, 0] << 42) | (rel[:, 1] << 21) | rel[:, 2]
    key, inverse = np.unique(key, return_inverse=True)
    mask = (1 << 21) - 1
    out = np.column_stack([key >> 42, (key >> 21) & mask, key & mask]) + lo
    return Cells(np.ascontiguousarray(out), float(resolution)), inverse.reshape(-1)


def posed(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``points`` (shape (n, 3)) moved by ``pose`` (4, 4): the cloud's frame to the world."""
    return points @ pose[:3, :3].T + pose[:3, 3]


UnknownSpace = Literal["free", "occupied"]


@dataclass(frozen=True, eq=False)
class CloudObstacle:
    """A kept cloud: its id, its occupied cells (world), and what was assumed of the
    space the camera did not see (``"free"``, or ``"occupied"`` behind the measured
    surface, already among the cells)."""

    id: str
    cells: Cells
    unknown: UnknownSpace = "free"

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id:
            raise InvalidRequest("must be a non-empty string", field="cloud.id")
        if len(self.cells) == 0:
            raise InvalidRequest("no cell is left to keep", field=f"{self.id}.points")

    def key(self) -> tuple:
        """What its geometry is (not its id): the cells' content."""
        import hashlib

        digest = hashlib.sha256(np.ascontiguousarray(self.cells.index).tobytes()).digest()
        return ("cloud", self.cells.resolution, len(self.cells), digest)
