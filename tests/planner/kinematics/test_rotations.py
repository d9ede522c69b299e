"""src/arduinobot/planner/kinematics/rotations.py and description.model.rpy_of: the closed forms of a matrix's quaternion and
roll-pitch-yaw agree with scipy's ``Rotation`` (their reference) to rounding, at gimbal
lock and for matrices that are not rotations too (which go to scipy)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from arduinobot.description.model import rpy_matrix, rpy_of
from arduinobot.planner.kinematics.rotations import (
    quaternion_of_matrix,
    unit_quaternion,
)


def _scipy(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rot = Rotation.from_matrix(r)
    return np.array(unit_quaternion(rot.as_quat())), rot.as_euler("xyz")


def test_the_closed_forms_agree_with_scipy_on_random_rotations():
    mats = list(Rotation.random(5000, random_state=3).as_matrix())
    # each branch of Shepperd's choice: the trace, or one diagonal entry, largest
    mats += [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
             np.diag([-1.0, -1.0, 1.0])]
    for r in mats:
        q, rpy = _scipy(r)
        assert np.abs(np.array(quaternion_of_matrix(r)) - q).max() < 1e-12
        assert quaternion_of_matrix(r)[3] >= 0.0
        assert np.abs(np.array(rpy_of(r)) - rpy).max() < 1e-9


def test_gimbal_lock_and_non_rotations_take_scipy_s_answer():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # scipy warns at gimbal lock
        for r in (Rotation.from_euler("xyz", [0.3, np.pi / 2, 0.2]).as_matrix(),
                  Rotation.from_euler("xyz", [0.3, -np.pi / 2, 0.2]).as_matrix(),
                  np.diag([1.0, 1.0, 1.001]),  # not orthonormal: scipy takes the nearest
                  np.eye(3) + 1e-6):
            q, rpy = _scipy(r)
            assert np.array(quaternion_of_matrix(r)) == pytest.approx(q, abs=1e-12)
            assert np.array(rpy_of(r)) == pytest.approx(rpy, abs=1e-12)


@pytest.mark.parametrize("pitch", [np.pi / 2, np.pi / 2 - 1e-7, np.pi / 2 - 1e-5,
                                   -np.pi / 2, -np.pi / 2 + 1e-8, -np.pi / 2 + 1e-4])
def test_rpy_of_gives_the_matrix_back_near_gimbal_lock(pitch: float) -> None:
    # near the lock roll and yaw are nearly one angle: each may move, the matrix may not
    # (an answer of scipy's as is was off by 9e-8 at 1e-7 from the lock)
    for roll, yaw in ((0.4, -1.1), (2.0, 0.7), (-3.0, 3.1)):
        r = rpy_matrix((roll, pitch, yaw))
        rpy = rpy_of(r)
        assert np.abs(rpy_matrix(rpy) - r).max() < 1e-14
        assert rpy[1] == pytest.approx(pitch, abs=1e-7)
