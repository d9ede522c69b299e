"""A point-cloud object as a request states it, checked (the ``points`` shape).

``{"id": "camera", "shape": "points", "points": {"format": "xyz32", "data": base64},
"resolution": 0.01, "frame": "world" | a link, "xyz": [...], "rpy": [...],
"padding": 0.01, "unknown": "free" | "occupied", "camera": {"link": name | "xyz"/"rpy",
"hfov", "vfov", "range"}}``: the points are in ``frame`` moved by ``xyz``/``rpy``;
``padding`` [m] is the self-filter's; ``camera`` is required with ``unknown:
"occupied"`` (its pose in the world, or a link's, moved by its ``xyz``/``rpy``).
Decoding the points is bounded (:mod:`.cloud`); everything that needs the robot (a
link's pose, the self-filter) is the planner's (:mod:`arduinobot.planner.collision.cloud_keep`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.cloud import DecodedPoints, UnknownSpace, check_resolution, decode_points
from arduinobot.scene.cloud_filter import DEFAULT_PADDING
from arduinobot.scene.obstacles import finite_vec

KEYS = frozenset({"id", "shape", "points", "resolution", "frame", "xyz", "rpy", "padding",
                  "unknown", "camera"})
#: [m] the largest self-filter padding
MAX_PADDING = 0.2


@dataclass(frozen=True)
class Placement:
    """A frame (``"world"`` or a link) and an offset in it (xyz [m], rpy [rad])."""

    frame: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class CloudSpec:
    """A checked ``points`` object (see the module's docstring).

    Attributes:
        camera: the camera's hfov, vfov and range as given (checked with its pose).
        camera_at: where the camera is, with ``unknown: "occupied"``.
    """

    id: str
    points: DecodedPoints
    resolution: float
    at: Placement
    padding: float
    unknown: UnknownSpace
    camera: Mapping[str, Any] | None
    camera_at: Placement | None
    where: str

    @classmethod
    def from_mapping(cls, data: object, *, link_names: Sequence[str],
                     where: str = "object") -> CloudSpec:
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object", field=where)
        extra = sorted(set(data) - KEYS)
        if extra:
            raise InvalidRequest(f"unknown field(s) {', '.join(extra)}", field=where)
        oid = data.get("id")
        if not isinstance(oid, str) or not oid:
            raise InvalidRequest("must be a non-empty string", field=f"{where}.id")
        if data.get("shape", "points") != "points":
            raise InvalidRequest(f"{data.get('shape')!r} is not 'points'", field=f"{where}.shape")
        if "points" not in data:
            raise InvalidRequest("is required", field=f"{where}.points")
        if "resolution" not in data:
            raise InvalidRequest("is required", field=f"{where}.resolution")
        resolution = check_resolution(data["resolution"], field=f"{where}.resolution")
        at = _placement(data, link_names, where, frame_key="frame")
        padding = data.get("padding", DEFAULT_PADDING)
        if isinstance(padding, bool) or not isinstance(padding, (int, float)) \
                or not math.isfinite(padding) or not 0 <= padding <= MAX_PADDING:
            raise InvalidRequest(f"{padding!r} must be from 0 to {MAX_PADDING} [m]",
                                 field=f"{where}.padding")
        unknown = data.get("unknown", "free")
        if unknown not in ("free", "occupied"):
            raise InvalidRequest(f"{unknown!r} is not 'free' or 'occupied'",
                                 field=f"{where}.unknown")
        camera = data.get("camera")
        camera_at = None
        if unknown == "occupied":
            if not isinstance(camera, Mapping):
                raise InvalidRequest("unknown: occupied needs the camera {link or xyz/rpy, "
                                     "hfov, vfov, range}", field=f"{where}.camera")
            extra = sorted(set(camera) - {"link", "xyz", "rpy", "hfov", "vfov", "range"})
            if extra:
                raise InvalidRequest(f"unknown field(s) {', '.join(extra)}",
                                     field=f"{where}.camera")
            camera_at = _placement(camera, link_names, f"{where}.camera", frame_key="link")
        # the points last: the cheap checks refuse a bad request before the decoding
        points = decode_points(data["points"], field=f"{where}.points")
        return cls(oid, points, resolution, at, float(padding), unknown,
                   camera if unknown == "occupied" else None, camera_at, where)


def _placement(data: Mapping[str, Any], link_names: Sequence[str], where: str, *,
               frame_key: str) -> Placement:
    frame = data.get(frame_key, "world")
    if not isinstance(frame, str) or (frame != "world" and frame not in link_names):
        raise InvalidRequest(f"{frame!r} is neither 'world' nor a link of the robot",
                             field=f"{where}.{frame_key}",
                             details={"links": sorted(link_names)})
    x, y, z = finite_vec(data.get("xyz", (0.0, 0.0, 0.0)), 3, f"{where}.xyz")
    r, p, w = finite_vec(data.get("rpy", (0.0, 0.0, 0.0)), 3, f"{where}.rpy")
    return Placement(frame, (x, y, z), (r, p, w))
