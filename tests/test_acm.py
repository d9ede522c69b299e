from description import load_description
from planner.acm import AllowedCollisionMatrix
from planner.acm_gen import compute_acm


def test_from_srdf_and_pairs_are_unordered():
    acm = AllowedCollisionMatrix.from_srdf(load_description().srdf)
    assert acm.allowed("base_plate", "base_link")
    assert acm.reason("base_link", "base_plate") == "Adjacent"
    assert not acm.allowed("base_link", "claw_support")


def test_generation_adjacent_and_sound_never():
    d = load_description()
    r = compute_acm(d, samples=200, seed=1)
    reasons = {frozenset((p.link1, p.link2)): p.reason for p in r.disabled}
    assert reasons[frozenset(("claw_support", "gripper_left"))] == "Adjacent"
    # pairs seen colliding are never disabled, and unproven pairs stay checked
    for (a, b), n in r.collision_counts.items():
        if n:
            assert reasons.get(frozenset((a, b))) in (None, "Adjacent", "Always")
    for a, b in r.unproven:
        assert frozenset((a, b)) not in reasons
    # the fingers are 6 mm apart when closed: no bound may call them "Never"
    assert reasons.get(frozenset(("gripper_right", "gripper_left"))) != "Never"
