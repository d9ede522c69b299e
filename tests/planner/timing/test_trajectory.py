"""The blended curve and the sampled JointTrajectory (shape, exact end, export, at(t))."""

import csv
import io
import json

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import load_description
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.path_limits import ActiveLimits
from arduinobot.planner.timing.curve import build_curve
from arduinobot.planner.timing.ruckig_timing import JerkLimitedTiming
from arduinobot.planner.timing.trajectory import JointTrajectory, sample_times
from arduinobot.scene.obstacles import Obstacle
from tests.helpers.timing import DYN, NAMES, WORLD, WP, active_limits


def test_blended_curve_is_c2_and_inside_corner_triangles():
    curve = build_curve(WP, None)
    assert [c.kind for c in curve.corners] == ["blend", "blend"]
    sec = curve.sections[0]
    s = np.linspace(0.0, sec.length, 20001)
    q, d1, d2 = sec(s), sec(s, 1), sec(s, 2)
    np.testing.assert_allclose(q[0], WP[0], atol=1e-12)
    np.testing.assert_allclose(q[-1], WP[-1], atol=1e-12)
    # derivatives agree with finite differences: no jumps in q' or q''
    fd1 = np.diff(q, axis=0) / np.diff(s)[:, None]
    assert np.abs(fd1 - 0.5 * (d1[1:] + d1[:-1])).max() < 1e-5
    fd2 = np.diff(d1, axis=0) / np.diff(s)[:, None]
    assert np.abs(fd2 - 0.5 * (d2[1:] + d2[:-1])).max() < 1e-2
    assert np.linalg.norm(d1, axis=1).max() <= 1.0 + 1e-12
    # every point stays within the waypoints' bounding box (convex: within joint limits)
    assert np.all(q >= WP.min(axis=0) - 1e-12) and np.all(q <= WP.max(axis=0) + 1e-12)


def test_a_jet_is_its_orders_one_by_one_and_refuses_an_order_past_three():
    sec = build_curve(WP, None).sections[0]
    k, sigma = sec.locate(np.linspace(-0.1, sec.length + 0.1, 57))
    for order, d in zip(range(4), sec.jet(k, sigma)):
        np.testing.assert_array_equal(d, sec.in_piece(k, sigma, order))
    for bad in ((0, 4), (-1,)):
        with pytest.raises(InvalidRequest, match="not supported") as e:
            sec.jet(k, sigma, bad)
        assert e.value.details["field"] == "order"


# a gantry: two prismatic joints carry a 2 cm ball in the plane, so joint space is the
# plane [m] and a blend cuts its corner in both
GANTRY = """<robot name="gantry">
  <link name="base"/>
  <link name="carriage"/>
  <link name="tip"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="-0.5" upper="1.5" effort="10" velocity="1"/></joint>
  <joint name="y" type="prismatic"><parent link="carriage"/><child link="tip"/>
    <axis xyz="0 1 0"/><limit lower="-0.5" upper="1.5" effort="10" velocity="1"/></joint>
</robot>"""
SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@pytest.fixture(scope="module")
def gantry(tmp_path_factory):
    f = tmp_path_factory.mktemp("gantry") / "gantry.urdf"
    f.write_text(GANTRY)
    return load_description(f, env={})


def test_colliding_blend_is_shrunk_then_becomes_a_stop(gantry):
    # a 12.5 cm block inside each corner, 5 mm off both edges (beyond the ball's 2 cm):
    # the straight edges are free, every blend the corner can take in two halvings
    # (radius 0.25, 0.125, 0.0625 m) crosses the block
    block = (0.125, 0.125, 0.1)
    world = CollisionWorld(gantry, obstacles=(
        Obstacle("in_1", "box", size=block, xyz=(0.9125, 0.0875, 0.0)),
        Obstacle("in_2", "box", size=block, xyz=(0.9125, 0.9125, 0.0))))
    assert world.first_invalid(interpolate(SQUARE, 0.001)) == -1
    curve = build_curve(SQUARE, world, max_shrinks=2)
    assert [(c.kind, c.shrinks) for c in curve.corners] == [("stop", 3), ("stop", 3)]
    assert len(curve.sections) == 3  # rest at each waypoint, straight edges only
    for sec in curve.sections:
        assert sec.kinds == ("line",)
    # the blocks decide it: a third halving (0.03125 m) clears them, and without them
    # each corner keeps its full blend
    assert [(c.kind, c.radius) for c in build_curve(SQUARE, world, max_shrinks=3).corners] \
        == [("blend", 0.03125)] * 2
    assert [(c.kind, c.radius) for c in build_curve(SQUARE, CollisionWorld(gantry)).corners] \
        == [("blend", 0.25)] * 2


def test_blends_are_checked_against_the_real_world():
    curve = build_curve(WP, WORLD)
    for sec in curve.sections:
        assert WORLD.first_invalid(sec.dense(0.002)) == -1


def test_sample_times_end_exactly_at_duration():
    ts = sample_times(1.234, 100.0)
    assert ts[0] == 0.0 and ts[-1] == 1.234
    assert np.all(np.diff(ts) > 0) and np.diff(ts).max() <= 0.01 + 1e-12
    assert sample_times(1.0, 10.0)[-1] == 1.0 and len(sample_times(1.0, 10.0)) == 11
    for bad in (0.5, 1001.0, float("nan")):
        with pytest.raises(InvalidRequest) as e:
            sample_times(1.0, bad)
        assert e.value.field == "sample_rate"


@pytest.fixture(scope="module")
def traj():
    timing = JerkLimitedTiming(DYN).parameterise(build_curve(WP, WORLD),
                                                 ActiveLimits.from_limits(active_limits()))
    return JointTrajectory.sample(timing, DYN.torques_batch, joint_names=NAMES,
                                  sample_rate=50.0)


def test_trajectory_shape_and_exact_final_state(traj):
    assert traj.joint_names == NAMES
    assert traj.times[-1] == traj.duration > 0
    np.testing.assert_array_equal(traj.positions[-1], WP[-1])
    np.testing.assert_array_equal(traj.velocities[-1], 0.0)
    np.testing.assert_array_equal(traj.positions[0], WP[0])
    p = traj.points[-1]
    assert p.time_from_start == traj.duration and len(p.effort) == 4
    # effort is inverse dynamics of the sampled state
    np.testing.assert_allclose(traj.efforts, DYN.torques_batch(
        traj.positions, traj.velocities, traj.accelerations))


def test_at_matches_samples_and_clamps(traj):
    i = len(traj.times) // 2
    p = traj.at(float(traj.times[i]))
    np.testing.assert_allclose(p.positions, traj.positions[i], atol=1e-12)
    np.testing.assert_allclose(p.velocities, traj.velocities[i], atol=1e-12)
    np.testing.assert_allclose(p.effort, traj.efforts[i], atol=1e-9)
    assert traj.at(traj.duration + 5).positions == tuple(WP[-1])
    with pytest.raises(InvalidRequest):
        traj.at(float("nan"))


def test_velocity_is_the_derivative_of_position(traj):
    ts = np.linspace(0, traj.duration, 40001)
    q, qd, _ = traj.evaluate(ts)
    fd = np.diff(q, axis=0) / np.diff(ts)[:, None]
    assert np.abs(fd - 0.5 * (qd[1:] + qd[:-1])).max() < 1e-3


def test_json_and_csv_export(traj):
    data = json.loads(traj.to_json())
    assert data["joint_names"] == list(NAMES)
    assert len(data["points"]) == len(traj.times)
    assert data["points"][-1]["time_from_start"] == traj.duration
    assert data["points"][-1]["positions"] == list(WP[-1])
    rows = list(csv.reader(io.StringIO(traj.to_csv())))
    assert rows[0][0] == "time_from_start" and rows[0][1] == "joint_1.position"
    assert len(rows) == len(traj.times) + 1 and len(rows[1]) == 1 + 4 * 4
    assert float(rows[-1][0]) == traj.duration


def test_sample_times_refuses_more_than_max_samples_before_making_them():
    from arduinobot.contract.errors import InvalidRequest
    from arduinobot.planner.timing.trajectory import sample_times
    assert len(sample_times(10.0, 100.0, max_samples=1002)) == 1001
    with pytest.raises(InvalidRequest) as e:
        sample_times(10.0, 100.0, max_samples=1000)
    d = e.value.details
    assert e.value.field == "sample_rate" and d["limit"] == 1000
    assert d["max_sample_rate"] == 99.0 and len(sample_times(10.0, 99.0, max_samples=1000)) <= 1000
