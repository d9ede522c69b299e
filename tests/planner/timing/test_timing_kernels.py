"""The compiled timing and verification kernels against the numpy they replaced.

Each reference below is the numpy implementation the kernel replaced, kept here verbatim
in substance: the kernels must give the same numbers (bounds, states, ratios), so the
same trajectories and the same verification reports.
"""

import numpy as np
import pytest

from arduinobot.contract.errors import TrajectoryError
from arduinobot.planner.path_limits import ActiveLimits, Derating, torque_coefficients
from arduinobot.planner.timing.curve import PathCurve, build_curve
from arduinobot.planner.timing.profiles import JerkLimited
from arduinobot.planner.timing.ruckig_timing import (
    _BLEND_SAMPLES,
    _LINE_SAMPLES,
    _TINY,
    JerkLimitedTiming,
)
from arduinobot.planner.timing.trajectory import JointTrajectory
from arduinobot.planner.timing.verify import Verifier, _of_peaks, _peak
from tests.helpers.timing import DYN, NAMES, WORLD, WP, active_limits

LIM = active_limits()


def _reference_piece_limits(dynamics, curve: PathCurve, limits: ActiveLimits):
    # JerkLimitedTiming.piece_limits as it was in numpy
    n = len(curve.lengths)
    counts = [_BLEND_SAMPLES if kind == "blend" else _LINE_SAMPLES for kind in curve.kinds]
    own = np.repeat(np.arange(n), counts)
    sigma = np.concatenate([np.linspace(0.0, L, m) for L, m in zip(curve.lengths, counts)])
    q, d1, d2, d3 = curve.jet(own, sigma)
    mt, bt, gt = torque_coefficients(dynamics, q, d1, d2)
    V, A, J, E = limits.velocity, limits.acceleration, limits.jerk, limits.effort
    d1, d2, d3, mt, bt, gt = (np.abs(x) for x in (d1, d2, d3, mt, bt, gt))
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])

    def least(budget, use):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(use > _TINY, np.broadcast_to(budget, use.shape) / use, np.inf)
        return np.minimum.reduceat(r.min(axis=1), first)

    slack_e = E - gt
    short = np.flatnonzero(np.minimum.reduceat((slack_e <= 0).any(axis=1), first))
    if len(short):
        return ("gravity", int(short[0]))
    v = np.minimum(least(V, d1), np.sqrt(np.minimum(least(0.5 * A, d2),
                                                    least(0.5 * slack_e, bt))))
    line = np.array([kind == "line" for kind in curve.kinds])
    j_free = least(J, d1)
    done = np.zeros(n, dtype=bool)
    vs, as_, js = v.copy(), np.zeros(n), np.zeros(n)
    for _ in range(30):
        w = v[own][:, None]
        a = np.minimum(least(A - d2 * w * w, d1), least(slack_e - bt * w * w, mt))
        a = np.where(line, a, np.minimum(a, least(0.5 * (J - d3 * w**3), 3 * d2 * w)))
        j = np.where(a > 0, least(J - 3 * d2 * w * np.maximum(a, 0)[own][:, None]
                                  - d3 * w**3, d1), -1.0)
        ok = ~done & (a > 0) & (j > 0) & (line | (j > 0.25 * j_free))
        vs[ok], as_[ok], js[ok] = v[ok], a[ok], j[ok]
        done |= ok
        if done.all():
            return vs, as_, js
        v = np.where(done, v, 0.8 * v)
    return ("speed", int(np.argmin(done)))


def _ratio(limit, *values, centre=None):
    # what Verifier.verify computes of one quantity: its peaks, over its limit
    limit = np.asarray(limit, float)
    return _of_peaks(limit, _peak(values, centre, len(limit)))


def _reference_ratio(limit, *values):
    # verify's ratio as it was in numpy
    limit = np.asarray(limit, float)
    peak = np.zeros(len(limit))
    for v in values:
        if len(v):
            np.maximum(peak, np.max(np.abs(v), axis=0), out=peak)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(limit > 0, peak / np.where(limit > 0, limit, 1.0),
                        np.where(peak > 0, np.inf, 0.0))


def _paths(seed: int, count: int) -> list[np.ndarray]:
    # random polylines in the joint box: corners of every sharpness, short and long edges
    rng = np.random.default_rng(seed)
    lo, hi = np.array(LIM.lower), np.array(LIM.upper)
    return [rng.uniform(lo, hi, size=(int(rng.integers(2, 7)), len(NAMES)))
            for _ in range(count)]


def _gentle_paths(seed: int, count: int) -> list[np.ndarray]:
    # polylines with mild corners (as a shortcut planner's): long edges, small turns
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        d = rng.normal(size=len(NAMES))
        pts = [rng.uniform(-0.5, 0.5, size=len(NAMES))]
        for _ in range(int(rng.integers(2, 5))):
            d = d / np.linalg.norm(d) + 0.3 * rng.normal(size=len(NAMES))
            pts.append(pts[-1] + rng.uniform(0.3, 1.0) * d / np.linalg.norm(d))
        out.append(np.array(pts))
    return out


def _derated(i: int) -> ActiveLimits:
    # scaled and derated limits, the effort limit biting on some
    f = (1.0, 0.5, 0.2, 0.05)[i % 4]
    return ActiveLimits.from_limits(LIM, Derating(velocity=f, acceleration=f, jerk=f,
                                                  effort=(1.0, 0.6, 0.3, 0.2)[i % 4]))


def test_piece_limits_equal_the_numpy_reference():
    timing = JerkLimitedTiming(DYN)
    compared = 0
    for i, path in enumerate(_paths(1, 40)):
        for radius in (0.25, 0.0):
            curve = build_curve(path, None, max_radius=radius)
            lim = _derated(i)
            for sec in curve.sections:
                ref = _reference_piece_limits(DYN, sec, lim)
                if isinstance(ref[0], str):
                    with pytest.raises(TrajectoryError) as e:
                        timing.piece_limits(sec, lim)
                    assert e.value.details["piece"] == ref[1]
                    continue
                got = timing.piece_limits(sec, lim)
                for g, r in zip(got, ref):
                    np.testing.assert_array_equal(g, r)
                compared += 1
    assert compared > 60


def test_piece_limits_refuse_as_the_reference_did():
    timing = JerkLimitedTiming(DYN)
    curve = build_curve(WP, None).sections[0]
    weak = ActiveLimits.from_limits(LIM, Derating(effort=0.001))
    ref = _reference_piece_limits(DYN, curve, weak)
    assert ref[0] == "gravity"
    with pytest.raises(TrajectoryError, match="gravity") as e:
        timing.piece_limits(curve, weak)
    assert e.value.details["piece"] == ref[1]


def test_compiled_states_equal_numpy_states():
    timing = JerkLimitedTiming(DYN)
    for i, path in enumerate(_paths(2, 12)):
        tim = timing.parameterise(build_curve(path, None, max_radius=(0.25, 0.0)[i % 2]),
                                  _derated(i))
        ts = np.concatenate([np.linspace(-0.1, tim.duration + 0.1, 3001), tim.t0,
                             [tim.duration]])
        for got, ref in zip(tim.evaluate(ts), tim.evaluate_numpy(ts)):
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-14)
        assert tim._packed is not None  # the compiled pass did run


def test_ratio_equals_the_numpy_reference():
    rng = np.random.default_rng(3)
    mid = rng.normal(size=4)
    for _ in range(20):
        vals = [rng.normal(size=(int(rng.integers(0, 50)), 4)) for _ in range(2)]
        lim = np.abs(rng.normal(size=4)) * rng.integers(0, 2, size=4)  # zero limits too
        np.testing.assert_array_equal(_ratio(lim, *vals), _reference_ratio(lim, *vals))
        np.testing.assert_array_equal(_ratio(lim, *vals, centre=mid),
                                      _reference_ratio(lim, *(v - mid for v in vals)))
    nan = np.array([[1.0, np.nan, 0.0, 2.0]])
    np.testing.assert_array_equal(_ratio(np.ones(4), nan), _reference_ratio(np.ones(4), nan))


class _OwnDynamics:
    # the same inverse dynamics behind another object: the verifier cannot reuse the
    # trajectory's efforts and recomputes them
    def torques_batch(self, q, qd, qdd):
        return DYN.torques_batch(q, qd, qdd)


def test_reused_sample_efforts_give_the_same_report():
    timing = JerkLimitedTiming(DYN)
    for i, path in enumerate(_paths(4, 6)):
        lim = _derated(i)
        tim = timing.parameterise(build_curve(path, None), lim)
        traj = JointTrajectory.sample(tim, DYN.torques_batch, joint_names=NAMES)
        a = Verifier(LIM, DYN, WORLD).verify(traj).to_dict()
        b = Verifier(LIM, _OwnDynamics(), WORLD).verify(traj).to_dict()
        assert a == b


def test_stop_floor_bounds_the_stops_and_keeps_the_choice():
    # the floor never exceeds the stop-at-every-waypoint timing, so skipping that timing
    # when the floor already loses leaves the profile's choice as it was
    profile = JerkLimited(DYN)
    timing = profile.timing
    skipped = 0
    for i, path in enumerate(_paths(5, 20) + _gentle_paths(6, 20)):
        # every other one at the request's limits (effort rarely biting: the floor is tight)
        lim = _derated(i) if i % 2 else ActiveLimits.from_limits(LIM)
        edges = build_curve(path, None, max_radius=0.0)
        stops = timing.parameterise(edges, lim)
        floor = timing.rest_to_rest_floor(edges, lim)
        assert 0.0 < floor <= stops.duration * (1 + 1e-12)
        curve = build_curve(path, None)
        blended = timing.parameterise(curve, lim)
        before = stops if stops.duration < blended.duration else blended  # as it was
        got = profile.parameterise(curve, path, lim)
        assert got.duration == before.duration
        skipped += floor * (1 - 1e-9) >= blended.duration
    assert skipped >= 5  # the floor does spare the stops' timing


def test_stop_floor_is_zero_for_a_blended_curve():
    curve = build_curve(WP, None)
    assert any(k == "blend" for s in curve.sections for k in s.kinds)
    assert JerkLimitedTiming(DYN).rest_to_rest_floor(curve, _derated(0)) == 0.0
