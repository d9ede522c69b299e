"""Markers in an image: OpenCV's ArUco detector (ArUco and AprilTag dictionaries, corners
refined to sub-pixel), each marker's pose in the camera's optical frame from its four
corners (IPPE for squares, then Levenberg-Marquardt), with what says how far to trust it:
the reprojection error, the marker's side in pixels and the angle it is seen at.
Needs OpenCV (the ``see`` extra)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from arduinobot.perception.intrinsics import Intrinsics
from arduinobot.perception.markers import cv_dictionary_name

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class MarkerView:
    """One marker seen.

    Attributes:
        id: the marker's id in its dictionary.
        corners: image corners [px], shape (4, 2), in OpenCV's order (top-left,
            top-right, bottom-right, bottom-left of the printed marker).
        pose: marker frame -> optical frame, shape (4, 4) [m].
        reprojection_error: RMS distance [px] between the corners and the pose's
            projection of them.
        side_px: the mean side of the marker in the image [px].
        angle: between the marker's normal and the ray from it to the camera [rad]
            (0: seen face on).
    """

    id: int
    corners: np.ndarray
    pose: np.ndarray
    reprojection_error: float
    side_px: float
    angle: float


def marker_points(size: float) -> np.ndarray:
    """The corners of a marker of side ``size`` [m] in its frame, shape (4, 3), in the
    order the detector gives them."""
    h = size / 2.0
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def find_markers(gray: np.ndarray, dictionary: str) -> list[tuple[int, np.ndarray]]:
    """Every marker of ``dictionary`` in the grey image: (id, corners shape (4, 2) [px])."""
    import cv2

    aruco = cv2.aruco
    params = aruco.DetectorParameters()
    params.cornerRefinementMethod = aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementWinSize = 5
    params.cornerRefinementMaxIterations = 100
    params.cornerRefinementMinAccuracy = 0.01
    d = aruco.getPredefinedDictionary(getattr(aruco, cv_dictionary_name(dictionary)))
    corners, ids, _ = aruco.ArucoDetector(d, params).detectMarkers(gray)
    if ids is None:
        return []
    return [(int(i), np.asarray(c, dtype=np.float64).reshape(4, 2))
            for i, c in zip(ids.ravel(), corners, strict=True)]


def _matrix(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    import cv2

    t = np.eye(4)
    t[:3, :3] = cv2.Rodrigues(rvec)[0]
    t[:3, 3] = np.ravel(tvec)
    return t


def marker_pose(marker_id: int, corners: np.ndarray, size: float,
                intrinsics: Intrinsics) -> MarkerView:
    """The pose of a marker of side ``size`` [m] from its image ``corners``: of IPPE's two
    candidates the one that reprojects best, refined by Levenberg-Marquardt."""
    import cv2

    obj = marker_points(size)
    img = np.ascontiguousarray(corners, dtype=np.float64).reshape(4, 1, 2)
    k, dist = intrinsics.matrix(), intrinsics.dist()
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, k, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for rv, tv in zip(rvecs[:n], tvecs[:n], strict=True):
        rv, tv = cv2.solvePnPRefineLM(obj, img, k, dist, rv.copy(), tv.copy())
        proj = cv2.projectPoints(obj, rv, tv, k, dist)[0].reshape(4, 2)
        err = float(np.sqrt(np.mean(np.sum((proj - corners) ** 2, axis=1))))
        if best is None or err < best[0]:
            best = (err, rv, tv)
    if best is None:  # IPPE always gives two for four distinct corners
        raise RuntimeError(f"solvePnP gave no pose for marker {marker_id}")
    err, rv, tv = best
    pose = _matrix(rv, tv)
    sides = np.linalg.norm(corners - np.roll(corners, -1, axis=0), axis=1)
    to_camera = -pose[:3, 3] / np.linalg.norm(pose[:3, 3])
    angle = float(np.arccos(np.clip(pose[:3, 2] @ to_camera, -1.0, 1.0)))
    return MarkerView(id=marker_id, corners=corners, pose=pose, reprojection_error=err,
                      side_px=float(np.mean(sides)), angle=angle)
