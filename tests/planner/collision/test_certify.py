"""Certified collision checking between samples (arduinobot.planner.collision.proof.certify), against FCL."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.certificate import Certificate, combine
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.proof.motion_check import interpolate
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.planner.timing.curve import build_curve
from arduinobot.scene.obstacles import Obstacle

NEEDLE = """<robot name="needle">
  <link name="base"/>
  <link name="needle">
    <collision><origin xyz="0.5 0 0"/><geometry><box size="1.0 0.0002 0.0002"/></geometry></collision>
  </link>
  <joint name="yaw" type="revolute"><parent link="base"/><child link="needle"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""


@pytest.fixture(scope="module")
def needle(tmp_path_factory):
    f = tmp_path_factory.mktemp("needle") / "needle.urdf"
    f.write_text(NEEDLE)
    d = load_description(f, env={})
    # a plate 0.2 mm thin across the needle's sweep, exactly between two samples that
    # are 0.002 rad apart: at the samples the needle is >= 0.6 mm from it
    mid = 0.101
    plate = Obstacle("plate", "box", size=(0.2, 0.0002, 0.05),
                     xyz=(0.7 * np.cos(mid), 0.7 * np.sin(mid), 0.0), rpy=(0.0, 0.0, mid))
    return CollisionWorld(d, obstacles=(plate,))


def test_a_graze_between_samples_is_refused(needle):
    path = np.array([[0.0], [0.2]])
    dense = interpolate(path, 0.002)
    assert needle.first_invalid(dense) == -1  # sampling at 0.002 rad misses the plate
    assert not needle.check(np.array([0.101])).valid  # ... which the needle crosses
    cert = Certifier(needle).path(path)
    assert not cert.free
    piece, sigma, pair, distance = cert.failure
    assert pair == ("needle", "plate") and distance <= 1e-5
    assert sigma == pytest.approx(0.101, abs=2e-3)


def test_without_samples_first_the_proof_alone_refuses_a_graze_and_a_crossing(needle):
    # (what a planner's re-check does: it sampled the edges itself)
    for path in ([[0.0], [0.2]], [[0.0], [0.101]], [[0.3], [-0.5]]):
        cert = Certifier(needle).path(np.array(path), sample_step=None)
        assert not cert.free and cert.failure[2] == ("needle", "plate")
        assert cert.failure[1] == pytest.approx(abs(0.101 - path[0][0]), abs=2e-3)
    assert Certifier(needle).path(np.array([[0.0], [0.09]]), sample_step=None).free


def test_a_motion_short_of_the_plate_is_certified_with_its_clearance(needle):
    cert = Certifier(needle, fraction=0.5).path(np.array([[0.0], [0.09]]))
    assert cert.free and cert.closest == ("needle", "plate")
    # the true gap at the end: the needle at 0.09 rad vs the plate at 0.101 rad, at the
    # plate's inner end (r = 0.6 m) it is about 0.6 * 0.011 - 0.0002 m
    true_gap = needle.check(np.array([0.09]), clearance=True).clearance
    assert 0 < cert.certified_clearance <= true_gap


@pytest.mark.parametrize("scene", ["self", "table"])
def test_certified_motions_are_free_at_every_fine_sample(scene):
    d = load_description()
    obs = () if scene == "self" else (Obstacle("table", "box", size=(0.6, 1.2, 0.05),
                                               xyz=(0, 1.0, 0.6)),)
    world = CollisionWorld(d, obstacles=obs)
    cert = Certifier(world, fraction=0.5)
    lim = d.robot.position_limits(world.kin.joint_names)
    rng = np.random.default_rng(5)
    free = refused = 0
    for _ in range(40):
        a = rng.uniform(lim[:, 0], lim[:, 1])
        b = np.clip(a + rng.normal(0, 0.3, 4), lim[:, 0], lim[:, 1])
        c = cert.path(np.array([a, b]))
        dense = interpolate(np.array([a, b]), 0.0005)
        if c.free:
            free += 1
            assert world.first_invalid(dense) == -1
            # the certified clearance is a lower bound on FCL's distance at any state
            idx = np.linspace(0, len(dense) - 1, 5).astype(int)
            assert c.certified_clearance <= world.min_clearance(dense[idx])[0] + 1e-9
        else:
            refused += 1
            k, sigma, pair, dist = c.failure
            q = a + (b - a) * sigma / np.linalg.norm(b - a)
            assert not world.check(q).valid or dist <= 1e-5
    assert free and refused  # both outcomes exercised


def test_blends_are_certified():
    d = load_description()
    world = CollisionWorld(d)
    wp = np.array([[0.0, 0.0, 0.0, 0.0], [0.6, 0.3, 0.2, 0.0], [1.0, -0.2, 0.5, 0.0]])
    curve = build_curve(wp, Certifier(world))
    assert any(c.kind == "blend" for c in curve.corners)
    assert Certifier(world).curve(curve.sections).free
    # each kept blend carries its proof, for the pipeline to reuse
    assert all(c.certificate is not None and c.certificate.free
               for c in curve.corners if c.kind == "blend")
    assert all(c.certificate is None for c in build_curve(wp, world).corners)


def test_a_blend_whose_bulge_crosses_an_obstacle_is_refused(needle):
    # a reversing blend from 0.05 rad: q(sigma) peaks at 0.1125 rad (sigma = L / 2) and
    # ends back at 0.05, so its ends are far from the plate at 0.101 rad, its bulge is not
    c = Certifier(needle)
    start, up, down, length = np.array([[0.05]]), np.array([[1.0]]), np.array([[-1.0]]), 0.2
    assert needle.check(np.array([0.05])).valid
    cert = c.pieces(start, up, down, np.array([length]), sample_step=0.05)
    assert not cert.free and cert.failure[2] == ("needle", "plate")
    # the same blend from further back stays short of the plate
    assert c.pieces(np.array([0.0]), up, down, np.array([0.15])).free


def test_the_planner_never_returns_a_path_that_grazes_between_samples(needle):
    from arduinobot.contract.errors import NoPathFound
    from arduinobot.planner.planning.goals import JointGoal
    from arduinobot.planner.planning.pathfinding.paths import PathPlanner, PathRequest
    pp = PathPlanner(needle, needle.description)
    # the straight line's samples are free, so the sampled search accepts it; its
    # certification fails, and a certified re-plan finds no way around in one joint
    with pytest.raises(NoPathFound):
        pp.solve(PathRequest(start=np.array([0.0]), goal=JointGoal({"yaw": 0.2}),
                             planning_time=0.2, seed=1))
    ok = pp.solve(PathRequest(start=np.array([0.0]), goal=JointGoal({"yaw": 0.09}), seed=1))
    assert Certifier(needle).path(ok.path).free


def test_a_bound_carried_to_the_next_piece_pays_for_a_jump(needle):
    # piece 1 ends at 0.05 rad, far from the plate; piece 2 starts at 0.1 rad and crosses
    # it between its samples: what piece 1 proved must not carry over the jump
    starts = np.array([[0.0], [0.1]])
    u = np.ones((2, 1))
    lengths = np.array([0.05, 0.002])
    cert = Certifier(needle).pieces(starts, u, u, lengths)
    assert not cert.free and cert.failure[0] == 1
    # the same pieces stopping short of the plate: free, with a clearance no larger
    # than the true gap at the end of piece 2
    short = Certifier(needle, fraction=0.5).pieces(starts, u, u, np.array([0.05, 0.0005]))
    assert short.free
    true_gap = needle.check(np.array([0.1005]), clearance=True).clearance
    assert 0 < short.certified_clearance <= true_gap


def test_an_edge_split_into_pieces_is_certified_as_soundly_as_whole():
    d = load_description()
    world = CollisionWorld(d)
    cert = Certifier(world, fraction=0.5)
    lim = d.robot.position_limits(world.kin.joint_names)
    rng = np.random.default_rng(9)
    checked = 0
    for _ in range(30):
        a = rng.uniform(lim[:, 0], lim[:, 1])
        b = np.clip(a + rng.normal(0, 0.4, 4), lim[:, 0], lim[:, 1])
        cuts = np.linspace(0.0, 1.0, 7)
        path = a + np.outer(cuts, b - a)
        whole, split = cert.path(np.array([a, b])), cert.path(path)
        assert whole.free == split.free
        if split.free:
            checked += 1
            dense = interpolate(np.array([a, b]), 0.01)
            assert split.certified_clearance <= world.min_clearance(dense)[0] + 1e-9
    assert checked


def test_combined_certificates_keep_the_worst_and_the_first_failure():
    ok1 = Certificate(True, 0.0, 0.02, ("a", "b"), None, 10, 1)
    ok2 = Certificate(True, 0.0, 0.005, ("c", "d"), None, 5, 0)
    bad = Certificate(False, 0.0, 0.0, ("e", "f"), (0, 0.1, ("e", "f"), 0.0), 3, 2)
    both = combine([ok1, ok2])
    assert both.free and both.certified_clearance == 0.005 and both.closest == ("c", "d")
    assert (both.bounds, both.exact) == (15, 1)
    worst = combine([ok1, bad, ok2])
    assert not worst.free and worst.failure == bad.failure and worst.closest == ("e", "f")
    with pytest.raises(ValueError):
        combine([])


def test_steps_after_the_closest_point_prove_no_more_than_it(needle):
    # once a clearance is certified, no later step proves more than it: a motion that
    # starts at its closest point needs fewer bounds than the same motion reversed
    # (fraction 0.5 would prove half of every bound), and still certifies about half
    # the true gap
    c = Certifier(needle, fraction=0.5)
    away = c.path(np.array([[0.09], [-0.8]]))
    back = c.path(np.array([[-0.8], [0.09]]))
    assert away.free and back.free and away.closest == back.closest == ("needle", "plate")
    true_gap = needle.check(np.array([0.09]), clearance=True).clearance
    for cert in (away, back):
        assert 0.45 * true_gap <= cert.certified_clearance <= true_gap
    # (without it, away needs more bounds than back: 20 against 16, measured; with it
    # 12 against 15, far steps proving their whole gap in both directions)
    assert away.bounds < back.bounds


def test_local_speed_is_sound_and_takes_longer_steps_by_the_arm():
    # the shipped arm (a mimic finger) by a table and a post: with the body's speed
    # where it is now (Certifier(local=True), the default) a motion certified free is
    # free on a dense walk, with at least the certified clearance; one that collides
    # there is refused; and the proofs need fewer bounds and exact distances
    d = load_description()
    obstacles = (Obstacle("table", "box", size=(0.8, 0.8, 0.04), xyz=(0.0, 0.7, 0.9)),
                 Obstacle("post", "cylinder", radius=0.05, length=1.2, xyz=(0.6, 0.6, 1.0)))
    world = CollisionWorld(d, obstacles=obstacles)
    local, every = (Certifier(world, fraction=0.5, local=flag) for flag in (True, False))
    lim = d.robot.position_limits(world.kin.joint_names)
    rng = np.random.default_rng(11)
    free = refused = 0
    work = [0, 0]
    for _ in range(30):
        a = rng.uniform(lim[:, 0], lim[:, 1])
        if not world.is_valid(a):
            continue
        edge = np.array([a, np.clip(a + rng.normal(0, 0.5, 4), lim[:, 0], lim[:, 1])])
        cert, ref = local.path(edge), every.path(edge)
        dense = interpolate(edge, 0.0005)
        collides = world.first_invalid(dense) >= 0
        assert cert.free == ref.free == (not collides)
        if cert.free:
            free += 1
            assert cert.certified_clearance <= world.min_clearance(dense[::50])[0] + 1e-9
            work[0] += cert.bounds + cert.exact
            work[1] += ref.bounds + ref.exact
        else:
            refused += 1
    assert free >= 10 and refused >= 2
    assert work[0] < work[1]


def test_a_pair_the_motion_does_not_move_is_certified_at_its_distance_not_half_a_bound():
    # an arm motion with the gripper closed: the fingers (6 mm apart, closer than
    # anything else here) keep their distance; with a clearance to report, the
    # certificate gives their distance (their convex hulls', exact but for rounding), not half
    # a loose OBB-tree bound, and stays below what FCL measures anywhere on the motion
    d = load_description()
    world = CollisionWorld(d)
    fingers = world.pair_names.index(("gripper_right", "gripper_left"))
    edge = np.array([[0.0, 0.0, 0.0, 0.0], [1.2, 0.5, 0.9, 0.0]])
    exact = world.pair_distance(edge[0], fingers)
    cert = Certifier(world, fraction=0.5).path(edge)
    assert cert.free and cert.closest == ("gripper_right", "gripper_left")
    assert exact - 1e-8 < cert.certified_clearance <= exact  # (the hulls' rounding slack)
    dense = interpolate(edge, 0.01)
    assert cert.certified_clearance <= world.min_clearance(dense)[0]
    # without a clearance to report (fraction 0), the proof asks for no exact distance
    assert Certifier(world).path(edge).certified_clearance < 0.5 * exact
    # a motion that moves the fingers is walked as before: its figure stays a bound
    moving = np.array([[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, -0.4]])
    walked = Certifier(world, fraction=0.5).path(moving)
    assert walked.free
    assert walked.certified_clearance <= world.min_clearance(interpolate(moving, 0.01))[0]


def test_loose_leaf_boxes_do_not_lead_the_walk_into_microns(needle, tmp_path):
    # an octagonal prism of long slivers (as CAD meshes have): its leaf boxes stick out
    # of it at the corners, so approaching it the trees' bound falls through zero tens
    # of millimetres before the prism. The walk used to take the small positive bounds
    # on the way and step geometrically toward the boxes' contact, certifying microns;
    # a hull query there proves the true gap's worth, in fewer bounds
    import trimesh
    trimesh.creation.cylinder(radius=0.1, height=0.6, sections=8).export(tmp_path / "p.stl")
    prism = Obstacle("prism", "mesh", mesh_path=str(tmp_path / "p.stl"), xyz=(0.7, 0, 0),
                     rpy=(0, 0, np.pi / 8))
    world = needle.with_scene((prism,))
    path = np.array([[0.4], [0.17]])
    true_gap = world.min_clearance(interpolate(path, 0.001))[0]
    assert 0.015 < true_gap < 0.025
    # (the trees alone prove a few millimetres at the end: nothing near the true gap)
    trees = world.lower_bound(path[-1])
    assert trees < 0.005
    cert = Certifier(world, fraction=0.5).path(path)
    assert cert.free and cert.closest == ("needle", "prism")
    assert 1e-3 < cert.certified_clearance <= true_gap
    assert cert.bounds <= 15  # (22 before, measured)


def test_a_grazing_path_is_planned_again_with_finer_samples_then_certified_edges(needle):
    # (the search samples edges 0.02 rad apart; a path grazing between samples is planned
    # again 0.01 rad apart, as before that step was doubled, and only then with every
    # edge certified: several times slower)
    from arduinobot.planner.planning.pathfinding.paths import FINEST_STEP, PLAN_STEP, PathPlanner
    pp = PathPlanner(needle, needle.description)
    finer = pp._retry()
    assert pp.step == PLAN_STEP and finer.step == PLAN_STEP / 2 == FINEST_STEP
    assert not finer.certify_edges and finer.room == pp.room
    strict = finer._retry()
    assert strict.certify_edges and strict.step == FINEST_STEP
    assert pp._retry() is finer  # built once


def test_a_claw_over_the_base_hollow_is_certified_millimetres_not_microns(course_ws):
    # the claw coming down over the course base: the hulls' bound shrinks geometrically
    # toward the hulls' contact while the meshes stay >= 12 mm apart; the walk used to
    # take it and certify 5 um (a false near contact, and its bounds); the part hulls,
    # asked where the hulls prove little, prove the gap without an exact query (and the
    # exact distance, asked once neither trees nor hulls prove EXACT_BELOW, where there
    # are no parts)
    from dataclasses import replace

    from arduinobot.planner.collision.proof import ladder
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})
    world = CollisionWorld(d)
    edge = np.array([[-1.2003252626449796, -0.41068828429081816, -0.8292884824147762,
                      -1.5144790307794396],
                     [-1.2630821198876434, -0.4732668406887417, -0.8518578215078093,
                      -1.474029975400117]])
    pair = world.pair_names.index(("base_link", "claw_support"))
    true_gap = min(world.pair_distance(q, pair) for q in interpolate(edge, 0.001))
    assert true_gap > 0.01
    cert = Certifier(world, fraction=0.5).path(edge, sample_step=None)
    assert cert.free and cert.closest == ("base_link", "claw_support")
    assert 0.001 < cert.certified_clearance <= true_gap
    assert cert.exact == 0
    # without parts (each link its hull alone): the exact distance proves the gap
    no_parts = CollisionWorld(d, bodies=replace(world.bodies, split=False))
    exact = Certifier(no_parts, fraction=0.5).path(edge, sample_step=None)
    assert exact.free and 0.0005 < exact.certified_clearance <= true_gap
    assert exact.exact > 0
    # the hulls alone (as before EXACT_BELOW): the same verdict, microns certified
    old, ladder.EXACT_BELOW = ladder.EXACT_BELOW, -np.inf
    try:
        hulls_only = Certifier(no_parts, fraction=0.5).path(edge, sample_step=None)
    finally:
        ladder.EXACT_BELOW = old
    assert hulls_only.free and hulls_only.certified_clearance < 1e-4
