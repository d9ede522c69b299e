"""Braking to rest within the effort limits (arduinobot.planner.timing.braking), shared by the moving
start and the clients' stops."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.contract.errors import TrajectoryError
from arduinobot.description import load_description
from arduinobot.planner.kinematics.dynamics import InverseDynamics
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.planner.timing.braking import (
    EFFORT_MARGIN,
    brake_to_rest,
    effort_ratio,
    effort_safe,
)

Q0 = np.array([0.3, 0.2, -0.1, 0.0])
V0 = np.array([0.8, -0.5, 0.6, 0.0])
A0 = np.zeros(4)


@pytest.fixture(scope="module")
def arm():
    d = load_description()
    return MotionPlanner(d).limits(1.0, 1.0), InverseDynamics(d.robot)


def test_the_brake_ends_at_rest_within_the_limits(arm):
    lim, _ = arm
    tr = brake_to_rest(Q0, V0, A0, velocity=lim.velocity, acceleration=lim.acceleration,
                       jerk=lim.jerk)
    q, qd, qdd = (np.array(x) for x in tr.at_time(tr.duration))
    assert np.allclose(qd, 0, atol=1e-9) and np.allclose(qdd, 0, atol=1e-9)
    for t in np.linspace(0, tr.duration, 50):
        _, v, a = tr.at_time(float(t))
        assert np.all(np.abs(v) <= lim.velocity + 1e-9)
        assert np.all(np.abs(a) <= lim.acceleration + 1e-9)


def test_a_tighter_effort_limit_gets_a_gentler_brake_that_fits_it(arm):
    lim, dyn = arm

    def make(f):
        return brake_to_rest(Q0, V0, A0, velocity=lim.velocity,
                             acceleration=f * lim.acceleration, jerk=f * lim.jerk)

    full = make(1.0)
    need = effort_ratio(full, dyn.torques_batch, lim.effort) * np.asarray(lim.effort)
    tight = 0.8 * need / EFFORT_MARGIN  # the full-scale brake no longer fits
    tr, ratio = effort_safe(make, dyn.torques_batch, tight)
    assert ratio <= EFFORT_MARGIN and tr.duration > full.duration
    assert effort_ratio(tr, dyn.torques_batch, tight, step=1e-4) <= 1.0


def test_no_stop_is_a_trajectory_error():
    with pytest.raises(TrajectoryError) as e:
        brake_to_rest(Q0, V0, A0, velocity=np.full(4, 1.0), acceleration=np.zeros(4),
                      jerk=np.zeros(4))
    assert e.value.details["stage"] == "brake"
