"""Markers to scene objects: an image, the camera's intrinsics and pose, and the marker
map give each seen object's full pose in the world frame, with an honest uncertainty
that becomes padding on the object planned with.

The uncertainty is a first-order estimate from the corner noise ``s`` [px] (the
reprojection error, at least :data:`CORNER_NOISE` px): across the view a corner shift
moves the marker ``Z s / f``, along it ``Z s / side_px``; a tilt of ``2 s / side_px``
[rad] swings the object's far side by that times its extent. Their root sum of squares is
the object's padding: a box seen at 2 mm uncertainty is planned 2 mm larger on every side.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.description.model import rpy_of as rpy_of_matrix
from arduinobot.perception.camera import CameraFrame, camera_frame
from arduinobot.perception.detect import MarkerView, find_markers, marker_pose
from arduinobot.perception.errors import MarkerRefused, NoMarker, UnknownMarker
from arduinobot.perception.image import ImageFormat, decode_gray
from arduinobot.perception.intrinsics import Intrinsics
from arduinobot.perception.markers import MarkedObject, MarkerMap
from arduinobot.scene.obstacles import Obstacle

log = logging.getLogger(__name__)

CORNER_NOISE = 0.5  # [px]: what sub-pixel refinement gets on a sharp corner, at best
MIN_SIDE_PX = 20.0  # [px]: a smaller marker's corners say little about its pose
MAX_ANGLE = math.radians(65.0)  # [rad]: beyond, the marker's pose is a guess


def _xyz(t: np.ndarray) -> tuple[float, float, float]:
    return (float(t[0, 3]), float(t[1, 3]), float(t[2, 3]))


@dataclass(frozen=True, eq=False)
class Detection:
    """An object seen through its marker.

    Attributes:
        marker: the marker's id; marked: what the map says it sits on.
        pose: the object's pose in the world frame, shape (4, 4) [m].
        marker_pose: the marker's pose in the world frame, shape (4, 4) [m].
        view: the marker as the camera saw it (corners, pose in the optical frame).
        uncertainty: the estimated position uncertainty of the object's surface [m]
            (see the module doc); the padding its obstacle gets.
    """

    marker: int
    marked: MarkedObject
    pose: np.ndarray
    marker_pose: np.ndarray
    view: MarkerView
    uncertainty: float

    def obstacle(self, *, padded: bool = True) -> Obstacle:
        """The scene object, ``uncertainty`` larger on every side if ``padded``."""
        o, pad = self.marked, (self.uncertainty if padded else 0.0)
        xyz, rpy = _xyz(self.pose), rpy_of_matrix(self.pose[:3, :3])
        return Obstacle(o.id, o.geometry.grown(pad), xyz=xyz, rpy=rpy,
                        where=f"markers.objects.{self.marker}")

    def to_dict(self) -> dict[str, object]:
        """The wire's detection: the object's and the marker's pose (world frame)."""
        return {"marker": self.marker, "object": self.marked.id,
                "xyz": list(_xyz(self.pose)), "rpy": list(rpy_of_matrix(self.pose[:3, :3])),
                "marker_xyz": list(_xyz(self.marker_pose)),
                "marker_rpy": list(rpy_of_matrix(self.marker_pose[:3, :3])),
                "reprojection_error": self.view.reprojection_error,
                "side_px": self.view.side_px, "angle": self.view.angle,
                "uncertainty": self.uncertainty}


@dataclass(frozen=True, eq=False)
class Perception:
    """What one image showed: its detections (by marker id) and the camera they were
    measured from."""

    detections: tuple[Detection, ...]
    camera: CameraFrame
    intrinsics: Intrinsics
    image_size: tuple[int, int]  # (width, height) [px]


def uncertainty(view: MarkerView, intrinsics: Intrinsics, extent: float) -> float:
    """The first-order position uncertainty [m] of an object of ``extent`` [m] seen
    through ``view`` (see the module doc)."""
    s = max(view.reprojection_error, CORNER_NOISE)
    z = float(view.pose[2, 3])
    f = 0.5 * (intrinsics.fx + intrinsics.fy)
    across = z * s / f
    along = z * s / view.side_px
    tilt = 2.0 * s / view.side_px
    return float(math.sqrt(2 * across**2 + along**2 + (tilt * extent) ** 2))


def locate(gray: np.ndarray, *, markers: MarkerMap, intrinsics: Intrinsics,
           camera: CameraFrame, min_side_px: float = MIN_SIDE_PX,
           max_angle: float = MAX_ANGLE) -> tuple[Detection, ...]:
    """The objects the markers in ``gray`` (shape (height, width)) show, in the world.

    Raises:
        NoMarker: no marker of the map's dictionary is seen.
        UnknownMarker: a marker is seen whose id the map lacks.
        MarkerRefused: a marker is smaller than ``min_side_px`` [px] or seen at more than
            ``max_angle`` [rad] off its normal.
    """
    seen = find_markers(gray, markers.dictionary)
    if not seen:
        raise NoMarker(markers.dictionary)
    unknown = sorted({i for i, _ in seen if i not in markers.objects})
    if unknown:
        raise UnknownMarker(unknown, list(markers.objects))
    out: list[Detection] = []
    for mid, corners in sorted(seen, key=lambda s: s[0]):
        view = marker_pose(mid, corners, markers.size, intrinsics)
        if view.side_px < min_side_px:
            raise MarkerRefused(mid, "too_small",
                                f"{view.side_px:.1f} px across, under {min_side_px:g} px",
                                {"side_px": view.side_px, "min_side_px": min_side_px})
        if view.angle > max_angle:
            raise MarkerRefused(mid, "grazing",
                                f"seen {math.degrees(view.angle):.0f} deg off its normal, "
                                f"over {math.degrees(max_angle):.0f} deg",
                                {"angle": view.angle, "max_angle": max_angle})
        obj = markers.objects[mid]
        marker_world = camera.pose @ view.pose
        pose = marker_world @ np.linalg.inv(obj.offset.matrix())
        u = uncertainty(view, intrinsics, obj.extent())
        log.debug("marker %d -> %s at %s (reprojection %.2f px, %.1f px, %.0f deg, +-%.1f mm)",
                  mid, obj.id, _xyz(pose), view.reprojection_error, view.side_px,
                  math.degrees(view.angle), 1e3 * u)
        out.append(Detection(marker=mid, marked=obj, pose=pose, marker_pose=marker_world,
                             view=view, uncertainty=u))
    ids = [d.marked.id for d in out]
    if len(set(ids)) != len(ids):  # the map gives each object one marker
        raise UnknownMarker([d.marker for d in out if ids.count(d.marked.id) > 1],
                            list(markers.objects))
    return tuple(out)


def perceive(image: bytes | np.ndarray, *, description: Description, markers: MarkerMap,
             camera: str, intrinsics: Intrinsics,
             state: Mapping[str, float] | None = None,
             image_format: ImageFormat | None = None,
             min_side_px: float = MIN_SIDE_PX, max_angle: float = MAX_ANGLE) -> Perception:
    """Decode ``image`` (PNG/JPEG bytes, or 8-bit grey already decoded, shape (height,
    width): a topic's, :mod:`.raw_image`), find the map's markers and place their objects
    in the world, the camera ``link`` at the model's ``state`` (joint -> [rad]).

    Raises:
        ImageInvalid, NoMarker, UnknownMarker, MarkerRefused: see :func:`locate`;
        InvalidRequest: an unknown camera link or joint (``field`` names it), or an image
            whose size is not the intrinsics'.
    """
    frame = camera_frame(description, camera, state)  # a bad link fails before decoding
    gray = image if isinstance(image, np.ndarray) else \
        decode_gray(image, image_format=image_format)
    h, w = gray.shape
    if intrinsics.width and (intrinsics.width, intrinsics.height) != (w, h):
        raise InvalidRequest(f"the image is {w} x {h} px but the intrinsics are for "
                             f"{intrinsics.width} x {intrinsics.height}", field="intrinsics")
    dets = locate(gray, markers=markers, intrinsics=intrinsics, camera=frame,
                  min_side_px=min_side_px, max_angle=max_angle)
    return Perception(detections=dets, camera=frame, intrinsics=intrinsics,
                      image_size=(w, h))
