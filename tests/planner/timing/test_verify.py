"""The verifier: passes good trajectories, catches each kind of violation, derates."""

import dataclasses
import json

import numpy as np

from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.path_limits import ActiveLimits, Derating
from arduinobot.planner.timing.curve import build_curve
from arduinobot.planner.timing.ruckig_timing import JerkLimitedTiming
from arduinobot.planner.timing.trajectory import JointTrajectory
from arduinobot.planner.timing.verify import TOLERANCE, Verifier, derate
from arduinobot.scene.obstacles import Obstacle
from tests.helpers.timing import DESC, DYN, NAMES, WORLD, WP, active_limits

LIMITS = active_limits()


def _traj(limits=LIMITS, wp=WP, rate=100.0):
    tim = JerkLimitedTiming(DYN).parameterise(build_curve(wp, None),
                                              ActiveLimits.from_limits(limits))
    return JointTrajectory.sample(tim, DYN.torques_batch, joint_names=NAMES,
                                  sample_rate=rate)


def test_good_trajectory_passes_with_full_report():
    rep = Verifier(LIMITS, DYN, WORLD, clearance_states=2).verify(_traj())
    assert rep.ok and rep.collision_free and not rep.violations
    assert rep.max_step <= 0.002 and rep.checked_states > 500
    assert set(rep.ratios) == {"position", "velocity", "acceleration", "jerk", "effort"}
    assert all(len(v) == 4 for v in rep.ratios.values())
    assert 0.5 < rep.worst["effort"] <= 1 + TOLERANCE
    assert rep.min_clearance > 0 and all(rep.closest_pair)
    d = json.loads(rep.to_json())
    assert d["worst_overall"]["ratio"] == max(d["worst"][k] for k in d["enforced"])


def test_tighter_limits_are_caught_and_derating_fixes_them():
    traj = _traj()
    tight = active_limits()
    # verify against half the effort the trajectory was planned for
    from types import SimpleNamespace
    half = SimpleNamespace(lower=tight.lower, upper=tight.upper, velocity=tight.velocity,
                           acceleration=tight.acceleration, jerk=tight.jerk,
                           effort=np.asarray(tight.effort) * 0.5)
    rep = Verifier(half, DYN, WORLD, clearance_states=0).verify(traj)
    assert not rep.ok and "effort" in rep.violations and rep.worst["effort"] > 1.5
    d = derate(rep, Derating())
    assert d.effort < 0.98 / rep.worst["effort"] + 1e-12 and d.velocity == 1.0
    retimed = _traj(half)
    assert Verifier(half, DYN, WORLD, clearance_states=0).verify(retimed).ok


def test_jerk_is_checked_by_finite_differences():
    from types import SimpleNamespace
    lim = SimpleNamespace(**{k: getattr(LIMITS, k) for k in
                             ("lower", "upper", "velocity", "acceleration", "effort")},
                          jerk=np.asarray(LIMITS.jerk) * 0.5)
    rep = Verifier(lim, DYN, WORLD, clearance_states=0).verify(_traj())
    assert "jerk" in rep.violations and 1.9 < rep.worst["jerk"] < 2.1
    assert Verifier(lim, DYN, WORLD, clearance_states=0).verify(
        _traj(), enforce_jerk=False).ok


def test_collision_between_samples_is_found():
    # a thin post swept through by the straight motion; 1 Hz samples alone would miss it
    wp = np.array([[-1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    traj = _traj(wp=wp, rate=1.0)
    world = CollisionWorld(DESC, obstacles=(Obstacle("post", "cylinder", radius=0.02,
                                                     length=3.0, xyz=(0.0, 1.3, 1.5)),))
    samples_hit = [world.first_invalid(traj.positions[i:i + 1]) >= 0
                   for i in range(len(traj.times))]
    rep = Verifier(LIMITS, DYN, world, clearance_states=0).verify(traj)
    assert not rep.ok and not rep.collision_free
    assert rep.colliding_pairs and any("post" in p for p in rep.colliding_pairs)
    assert 0 < rep.colliding_time < traj.duration
    assert not all(samples_hit)


def test_effort_peak_between_samples_is_found():
    # toppra bounds torque at gridpoints only: a peak between two samples must still fail
    from types import SimpleNamespace
    traj = _traj(rate=1.0)
    sampled = np.max(np.abs(traj.efforts), axis=0)
    ts = np.linspace(0.0, traj.duration, 20001)
    fine = np.max(np.abs(DYN.torques_batch(*traj.evaluate(ts))), axis=0)
    j = int(np.argmax(fine / sampled))
    assert fine[j] > 1.05 * sampled[j]  # the 1 Hz samples miss the peak
    effort = np.maximum(np.asarray(LIMITS.effort, float), fine * 2)
    effort[j] = 0.5 * (sampled[j] + fine[j])
    lim = SimpleNamespace(**{k: getattr(LIMITS, k) for k in
                             ("lower", "upper", "velocity", "acceleration", "jerk")},
                          effort=effort)
    rep = Verifier(lim, DYN, WORLD, clearance_states=0).verify(traj, enforce_jerk=False)
    assert not rep.ok and rep.violations == ("effort",)
    assert rep.ratios["effort"][j] > 1.0 + TOLERANCE


def test_with_a_certificate_limits_are_still_checked_between_samples():
    # collisions proven elsewhere: the grid for the limits alone still finds the peak
    from types import SimpleNamespace

    from arduinobot.planner.collision.proof.certificate import Certificate
    traj = _traj(rate=1.0)
    sampled = np.max(np.abs(traj.efforts), axis=0)
    ts = np.linspace(0.0, traj.duration, 20001)
    fine = np.max(np.abs(DYN.torques_batch(*traj.evaluate(ts))), axis=0)
    j = int(np.argmax(fine / sampled))
    effort = np.maximum(np.asarray(LIMITS.effort, float), fine * 2)
    effort[j] = 0.5 * (sampled[j] + fine[j])
    lim = SimpleNamespace(**{k: getattr(LIMITS, k) for k in
                             ("lower", "upper", "velocity", "acceleration", "jerk")},
                          effort=effort)
    proof = Certificate(True, 0.0, 0.01, ("a", "b"), None, 0, 0)
    rep = Verifier(lim, DYN, WORLD).verify(traj, enforce_jerk=False, certificate=proof)
    assert rep.certified and rep.collision_free and rep.min_clearance == 0.01
    assert not rep.ok and rep.violations == ("effort",)


def test_limit_grid_ignores_joints_that_do_not_move_and_thins_effort():
    from types import SimpleNamespace
    arm_only = WP.copy()
    arm_only[:, 3] = 0.0  # the gripper stays closed
    traj = _traj(wp=arm_only)
    ver = Verifier(LIMITS, DYN, WORLD)
    t, q, qd, qdd, stride = ver.limit_states(traj)
    # a gripper with a 100x shorter a/j than the arm's does not shrink the grid ...
    fast = SimpleNamespace(**{k: np.array(getattr(LIMITS, k), float) for k in
                              ("lower", "upper", "velocity", "acceleration", "jerk", "effort")})
    fast.jerk[3] *= 100.0
    t2, *_, stride2 = Verifier(fast, DYN, WORLD).limit_states(traj)
    assert len(t2) == len(t) and stride2 == stride
    # ... but it does when the gripper moves
    moving = _traj()
    assert len(Verifier(fast, DYN, WORLD).limit_states(moving)[0]) > \
        len(ver.limit_states(moving)[0])
    # the grid is at most 1% of the shortest a/j rise; effort every stride-th state at
    # 1% of the shortest a/j
    lim = LIMITS
    h = np.diff(t).max()
    aj = np.min(np.asarray(lim.acceleration) / np.asarray(lim.jerk))
    assert h <= max(0.01 * aj, 2.5e-4) + 1e-12
    assert stride >= 1 and stride * h <= 0.01 * aj + 1e-12


def test_limit_grid_misses_no_velocity_or_acceleration_peak_by_more_than_half_a_percent():
    # what the grid promises, against a 50x finer one; the slow-velocity limits make the
    # velocity's rule (1% of v over the peak acceleration), not a/j's, set the step
    from types import SimpleNamespace
    slow = SimpleNamespace(**{k: np.array(getattr(LIMITS, k), float) for k in
                              ("lower", "upper", "velocity", "acceleration", "jerk", "effort")})
    slow.velocity *= 0.05
    for lim in (LIMITS, slow):
        traj = _traj(lim)
        t, q, qd, qdd, _ = Verifier(lim, DYN, WORLD).limit_states(traj)
        _, qd_f, qdd_f = traj.evaluate(np.linspace(0.0, traj.duration, 50 * len(t)))
        for grid, fine, limit in ((qd, qd_f, lim.velocity), (qdd, qdd_f, lim.acceleration)):
            over = np.max(np.abs(fine), axis=0) - np.max(np.abs(grid), axis=0)
            assert np.all(over <= 0.005 * np.asarray(limit, float) + 1e-12)
    h_default = np.diff(Verifier(LIMITS, DYN, WORLD).limit_states(_traj())[0]).max()
    h_slow = np.diff(Verifier(slow, DYN, WORLD).limit_states(_traj(slow))[0]).max()
    assert h_slow < h_default


def test_non_finite_efforts_are_never_verified():
    # a 1e308 kg payload: the inverse dynamics' efforts overflow to NaN, whose ratio to
    # any limit compared false with "> 1", so the trajectory passed (issue 39, item 8)
    from arduinobot.planner.kinematics.dynamics import Payload

    traj = _traj()
    link = list(DYN.robot.links)[-1]
    zero = ((0.0, 0.0, 0.0),) * 3
    heavy = DYN.with_payloads([Payload(link, 1e308, (0.0, 0.0, 0.0), zero)])
    assert np.isnan(heavy.torques_batch(traj.positions, traj.velocities,
                                        traj.accelerations)).any()
    rep = Verifier(LIMITS, heavy, WORLD, clearance_states=0).verify(traj)
    assert not rep.ok and not rep.finite and "effort" in rep.violations
    assert rep.collision_free  # the failure is the numbers', not a collision


def test_a_nan_sample_is_never_verified():
    # a NaN acceleration: its ratio (and the jerk's, by differences) is NaN, which no
    # "> 1" comparison catches; with jerk not enforced, still no trajectory
    traj = _traj()
    acc = np.array(traj.accelerations, float)
    acc[len(acc) // 2, 1] = np.nan
    bad = dataclasses.replace(traj, accelerations=acc)
    rep = Verifier(LIMITS, DYN, WORLD, clearance_states=0).verify(bad, enforce_jerk=False)
    assert not rep.ok and not rep.finite and "acceleration" in rep.violations
    assert json.loads(rep.to_json())["finite"] is False
