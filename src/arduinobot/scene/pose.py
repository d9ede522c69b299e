"""Poses: URDF roll-pitch-yaw angles and rotation matrices, both ways.

The scene's objects and the robot's links (:mod:`arduinobot.description.model`'s
``Origin``) are placed the same way: ``xyz`` [m] and URDF ``rpy`` [rad] (fixed axes x,
then y, then z).
"""

from __future__ import annotations

import math
import warnings

import numpy as np


def rpy_matrix(rpy: tuple[float, float, float]) -> np.ndarray:
    """Rotation matrix of URDF roll-pitch-yaw (fixed axes x, then y, then z), shape (3, 3)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


#: how far from orthonormal (largest entry of R R^T - I) a matrix may be for the closed
#: forms (:func:`rpy_of`, quaternions); anything else goes to scipy, which takes the
#: nearest rotation
_ORTHONORMAL = 1e-9
#: [-] cos(pitch) below which roll and yaw are one angle (gimbal lock): yaw is then 0,
#: scipy's convention (above it the first column's direction still fixes yaw to rounding)
_LOCK_COS = 1e-12


def _dot(x: list[float], y: list[float]) -> float:
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


def rotation_rows(r: np.ndarray) -> list[list[float]] | None:
    """``r``'s rows as floats if it is a proper rotation matrix (3, 3), else None."""
    m = np.asarray(r, float)
    if m.shape != (3, 3):
        return None
    rows = m.tolist()  # nine floats: plain arithmetic beats numpy's per-call cost here
    u, v, w = rows
    grams = (_dot(u, u) - 1.0, _dot(v, v) - 1.0, _dot(w, w) - 1.0, _dot(u, v), _dot(u, w),
             _dot(v, w))
    if not all(abs(x) <= _ORTHONORMAL for x in grams):  # NaN fails too
        return None
    det = (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
           + u[2] * (v[0] * w[1] - v[1] * w[0]))
    return rows if det > 0.0 else None


def _scipy_rpy(r: np.ndarray) -> tuple[float, float, float]:
    from scipy.spatial.transform import Rotation  # only for a matrix that is no rotation

    with warnings.catch_warnings():  # at the lock scipy warns that it sets yaw to 0: known
        warnings.simplefilter("ignore", UserWarning)
        a = Rotation.from_matrix(np.asarray(r, float)).as_euler("xyz")
    return float(a[0]), float(a[1]), float(a[2])


def rpy_of(r: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw [rad] of a rotation matrix, shape (3, 3): the inverse of
    :func:`rpy_matrix`. At gimbal lock (pitch = +-pi/2) roll and yaw are one angle: yaw
    is 0 and roll takes it (scipy's convention); near it, yaw comes from the first
    column and roll and pitch are solved after it, so the three give ``r`` back to
    rounding. A matrix that is not a rotation: scipy's answer for the nearest one."""
    rows = rotation_rows(r)
    if rows is None:
        return _scipy_rpy(r)
    (a, b, c), (d, e, f), (g, _, _) = rows
    yaw = math.atan2(d, a) if math.hypot(a, d) > _LOCK_COS else 0.0
    cy, sy = math.cos(yaw), math.sin(yaw)
    # Rz(-yaw) r = Ry(pitch) Rx(roll): its first column gives pitch, its second row roll
    return (math.atan2(sy * c - cy * f, cy * e - sy * b), math.atan2(-g, cy * a + sy * d),
            yaw)
