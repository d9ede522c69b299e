"""Time-optimal timing: toppra on the blended curve, cached constraints, failures raise."""

import numpy as np
import pytest

from arduinobot.contract.errors import TrajectoryError
from arduinobot.planner.path_limits import ActiveLimits, Derating
from arduinobot.planner.timing.curve import build_curve
from arduinobot.planner.timing.toppra_timing import TimeOptimalTiming
from tests.helpers.timing import DYN, WP, active_limits

LIM = ActiveLimits.from_limits(active_limits())
CURVE = build_curve(WP, None)


def test_time_optimal_profile_is_near_limits_and_on_the_curve():
    tim = TimeOptimalTiming(DYN).parameterise(CURVE, LIM)
    ts = np.linspace(0, tim.duration, 20001)
    q, qd, qdd = tim.evaluate(ts)
    tau = DYN.torques_batch(q, qd, qdd)
    # toppra enforces only at gridpoints: within a few percent between them
    assert np.abs(qd).max() <= LIM.velocity.max() * 1.05
    assert np.all(np.abs(qdd) <= LIM.acceleration * 1.05)
    assert np.all(np.abs(tau) <= LIM.effort * 1.05)
    # and it is time-optimal: some limit is active
    assert max((np.abs(tau) / LIM.effort).max(), (np.abs(qdd) / LIM.acceleration).max()) > 0.95
    np.testing.assert_array_equal(q[-1], WP[-1])
    np.testing.assert_array_equal(qd[-1], 0.0)


def test_constraints_are_reused_per_limit_set():
    t = TimeOptimalTiming(DYN)
    a = t.constraints(LIM)
    assert t.constraints(ActiveLimits.from_limits(active_limits())) is a
    b = t.constraints(ActiveLimits.from_limits(active_limits(), Derating(effort=0.5)))
    assert b is not a


def test_lower_limits_take_longer():
    t = TimeOptimalTiming(DYN)
    fast = t.parameterise(CURVE, LIM).duration
    slow = t.parameterise(CURVE, ActiveLimits.from_limits(
        active_limits(0.3, 0.3))).duration
    assert slow > fast


def test_infeasible_becomes_trajectory_error():
    # an effort limit below gravity's torque: nothing can hold the arm, toppra returns None
    lim = ActiveLimits(LIM.velocity, LIM.acceleration, LIM.jerk, np.full(4, 1e-3))
    wp = np.array([[0.0, 0.8, 0.0, 0.0], [0.5, 1.0, 0.3, 0.0]])
    with pytest.raises(TrajectoryError) as e:
        TimeOptimalTiming(DYN).parameterise(build_curve(wp, None), lim)
    assert e.value.details["stage"] == "toppra"
    assert "return_code" in e.value.details
