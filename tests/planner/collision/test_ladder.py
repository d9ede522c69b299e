"""The certifier's near-contact ladder (planner/collision/proof/ladder.py): the still pairs'
remembered bound, and the rungs each certificate counts."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.certificate import combine
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.proof.ladder import Ladder
from arduinobot.planner.collision.world import CollisionWorld

# the claw coming down over the course base's hollow (tests/test_certify.py)
CLAW_EDGE = np.array([[-1.2003252626449796, -0.41068828429081816, -0.8292884824147762,
                       -1.5144790307794396],
                      [-1.2630821198876434, -0.4732668406887417, -0.8518578215078093,
                       -1.474029975400117]])


def test_the_remembered_still_bound_is_tight_on_convex_links_and_order_free(desc):
    world = CollisionWorld(desc)
    fingers = world.pair_names.index(("gripper_right", "gripper_left"))
    a = np.array([0.3, 0.2, 0.1, -0.3])
    b = np.array([-1.0, 0.6, 0.4, -0.3])  # the arm joints do not move the fingers
    c = np.array([0.3, 0.2, 0.1, -0.6])  # the finger joint does
    ladder = Ladder(world, clear=0.0)
    got = [ladder.still_bound(q, fingers, above=1e-5) for q in (a, b, c)]
    for q, g in zip((a, b, c), got):
        # the fingers are convex: their hulls' bound is FCL's distance less the hulls'
        # rounding slack (1e-9 m each)
        assert world.pair_distance(q, fingers) - 1e-8 < g <= world.pair_distance(q, fingers)
    assert abs(got[2] - got[0]) > 1e-4  # measured anew, not remembered
    # remembered by the world, by the finger joint's value: a and b are one entry
    assert len(world.remembered) == 2
    # the same figures in another order, in a world that has answered nothing yet
    fresh = CollisionWorld(desc)
    again = Ladder(fresh, clear=0.0)
    assert [again.still_bound(q, fingers, above=1e-5) for q in (c, b, a)] == got[::-1]


def test_a_certificate_counts_the_rungs_it_climbed(course_ws):
    # near the base's hollow the part hulls prove what the hulls cannot, without FCL;
    # without parts, FCL's exact distance does
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src], env={})
    world = CollisionWorld(d)
    cert = Certifier(world, fraction=0.5).path(CLAW_EDGE, sample_step=None)
    r = cert.rungs
    assert cert.free and r.trees > 0 and r.hulls > 0 and r.parts > 0
    assert r.exact == cert.exact == 0
    assert r.trees <= cert.bounds  # every tree bound the walk took is one of its bounds
    no_parts = CollisionWorld(d, bodies=replace(world.bodies, split=False))
    exact = Certifier(no_parts, fraction=0.5).path(CLAW_EDGE, sample_step=None)
    assert exact.free and exact.rungs.parts == 0
    assert exact.rungs.exact >= exact.exact > 0
    both = combine([cert, exact])
    assert both.rungs == cert.rungs + exact.rungs
    assert both.rungs.exact == exact.rungs.exact and both.rungs.parts == r.parts


def test_pairs_proven_before_the_walk_are_counted(desc):
    # an arm motion: the fingers' pair is one the finger joint alone moves; with a
    # clearance to report it is still instead (proven at its bound at the start, a hull
    # query the first time, then remembered by the world)
    world = CollisionWorld(desc)
    path = np.array([[0.0, 0.0, 0.0, -0.3], [0.4, 0.2, 0.1, -0.3]])
    plain = Certifier(world).path(path)
    assert plain.free and plain.rungs.still == 0 and plain.rungs.one_dim >= 1
    reported = Certifier(world, fraction=0.5).path(path)
    assert reported.free and reported.rungs.still == 1
    assert reported.rungs.still + reported.rungs.one_dim == plain.rungs.one_dim
    assert reported.rungs.hulls >= 1
    again = Certifier(world, fraction=0.5).path(path)
    assert again == replace(reported, rungs=replace(reported.rungs, hulls=reported.rungs.hulls - 1))
