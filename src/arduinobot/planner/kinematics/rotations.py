"""Orientations: quaternions (x, y, z, w, ROS's order), roll-pitch-yaw, rotation vectors.

Roll, pitch, yaw follow URDF: rotations about the fixed x, y, z axes in that order,
``R = Rz(yaw) Ry(pitch) Rx(roll)``. Thin wrappers over scipy's ``Rotation`` (already a
dependency through toppra) so every module converts the same way.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.model import rotation_rows

__all__ = ["unit_quaternion", "quaternion_of_rpy", "quaternion_of_matrix",
           "matrix_of_quaternion", "rotation_error"]  # roll-pitch-yaw of a matrix: model.rpy_of


def unit_quaternion(q: Sequence[float], *, where: str = "goal.orientation"
                    ) -> tuple[float, float, float, float]:
    """``q`` (x, y, z, w) normalised; w >= 0 (the same rotation's two quaternions, one form).

    Raises:
        InvalidRequest: not 4 finite numbers, or all zero.
    """
    try:
        v = np.array([float(x) for x in q])
    except (TypeError, ValueError):
        v = np.zeros(0)
    if v.shape != (4,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise InvalidRequest(f"{q!r} must be a quaternion: 4 finite numbers (x, y, z, w), "
                             "not all zero", field=where)
    v /= np.linalg.norm(v)
    if v[3] < 0:
        v = -v
    return tuple(float(x) for x in v)  # type: ignore[return-value]


def quaternion_of_rpy(rpy: Sequence[float], *, where: str = "goal.orientation.rpy"
                      ) -> tuple[float, float, float, float]:
    """The quaternion (x, y, z, w) of roll, pitch, yaw [rad]."""
    try:
        v = [float(x) for x in rpy]
    except (TypeError, ValueError):
        v = []
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise InvalidRequest(f"{rpy!r} must be 3 finite angles [rad] (roll, pitch, yaw)",
                             field=where)
    return unit_quaternion(Rotation.from_euler("xyz", v).as_quat(), where=where)


def matrix_of_quaternion(q: Sequence[float]) -> np.ndarray:
    """The rotation matrix of a unit quaternion (x, y, z, w), shape (3, 3)."""
    return Rotation.from_quat(np.asarray(q, float)).as_matrix()


def quaternion_of_matrix(r: np.ndarray) -> tuple[float, float, float, float]:
    """The quaternion (x, y, z, w), w >= 0, of a rotation matrix, shape (3, 3).

    Shepperd's closed form on nine floats (a service reply computes one per plan: scipy's
    ``Rotation`` costs ~35 us a call there); scipy for a matrix that is not a rotation."""
    rows = rotation_rows(r)
    if rows is None:
        return unit_quaternion(Rotation.from_matrix(np.asarray(r, float)).as_quat())
    (a, b, c), (d, e, f), (g, h, i) = rows
    tr = a + e + i
    if tr >= a and tr >= e and tr >= i:  # the largest component first: no cancellation
        s = 2.0 * math.sqrt(1.0 + tr)
        q = ((h - f) / s, (c - g) / s, (d - b) / s, 0.25 * s)
    elif a >= e and a >= i:
        s = 2.0 * math.sqrt(1.0 + a - e - i)
        q = (0.25 * s, (b + d) / s, (c + g) / s, (h - f) / s)
    elif e >= i:
        s = 2.0 * math.sqrt(1.0 - a + e - i)
        q = ((b + d) / s, 0.25 * s, (f + h) / s, (c - g) / s)
    else:
        s = 2.0 * math.sqrt(1.0 - a - e + i)
        q = ((c + g) / s, (f + h) / s, 0.25 * s, (d - b) / s)
    n = math.sqrt(sum(x * x for x in q))
    sign = -1.0 if q[3] < 0 else 1.0
    return tuple(sign * x / n for x in q)  # type: ignore[return-value]


def rotation_error(goal: np.ndarray, reached: np.ndarray) -> np.ndarray:
    """The rotation vector [rad] taking ``goal`` to ``reached`` (both (3, 3) or (m, 3, 3)),
    in the goal's frame: ``rotvec(goal^T reached)``, shape (3,) or (m, 3). Its component
    along an axis of the goal frame is what a per-axis tolerance bounds."""
    rel = np.swapaxes(goal, -1, -2) @ reached
    return Rotation.from_matrix(rel).as_rotvec()
