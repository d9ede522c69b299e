from arduinobot.description import load_description
from arduinobot.planner.collision.acm import AllowedCollisionMatrix
from arduinobot.planner.collision.acm_gen import compute_acm


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
    assert "Never-proven" in reasons.values()
    for a, b in r.unproven:
        assert frozenset((a, b)) not in reasons
    # the fingers are 6 mm apart when closed: no bound may call them "Never"
    assert reasons.get(frozenset(("gripper_right", "gripper_left"))) is None


def _no_srdf(d):
    import dataclasses
    return dataclasses.replace(d, srdf=None)


def test_joint_connected_and_rigidly_attached_links_are_always_allowed(tmp_path):
    # a camera on a fixed joint to the base, a bracket on a fixed joint to the camera
    # (a chain of fixed joints), and a link without geometry between arm and base
    box = '<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>'
    (tmp_path / "r.urdf").write_text(f"""<robot name="r">
      <link name="base">{box}</link><link name="cam">{box}</link><link name="bracket">{box}</link>
      <link name="hub"/><link name="arm">{box}</link>
      <joint name="c" type="fixed"><parent link="base"/><child link="cam"/></joint>
      <joint name="b" type="fixed"><parent link="cam"/><child link="bracket"/></joint>
      <joint name="h" type="revolute"><parent link="base"/><child link="hub"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="a" type="fixed"><parent link="hub"/><child link="arm"/></joint></robot>""")
    from arduinobot.description import load_description as load
    acm = AllowedCollisionMatrix.for_description(load(tmp_path / "r.urdf", env={}))
    assert acm.allowed("base", "cam") and acm.allowed("cam", "bracket")
    assert acm.allowed("base", "bracket")  # rigid through a chain of fixed joints
    assert acm.allowed("arm", "base")      # joined through 'hub', which has no geometry
    assert not acm.allowed("arm", "cam") and not acm.allowed("arm", "bracket")


def test_srdf_pairs_add_to_the_adjacent_ones():
    d = load_description()
    acm = AllowedCollisionMatrix.for_description(d)
    assert all(acm.allowed(p.link1, p.link2) for p in d.srdf.disabled_collisions)
    acm0 = AllowedCollisionMatrix.for_description(_no_srdf(d))
    assert acm0.allowed("base_link", "base_plate")
    assert acm0.allowed("claw_support", "horizontal_arm")  # fixed joint
    assert not acm0.allowed("base_link", "horizontal_arm")


def test_proven_pairs_never_collide_anywhere_sampled():
    import numpy as np

    from arduinobot.planner.collision.acm_proof import prove_never
    from arduinobot.planner.collision.world import CollisionWorld
    world = CollisionWorld(_no_srdf(load_description()))
    r = prove_never(world, seed=3)
    assert len(r.proven) >= 3  # the sphere bound of acm_gen proved none of them
    assert not set(r.proven) & set(r.touching)
    # the fingers close to a few millimetres: they must not be proven apart
    assert ("gripper_right", "gripper_left") not in r.proven
    lim = world.description.robot.position_limits(world.kin.joint_names)
    rng = np.random.default_rng(11)
    qs = rng.uniform(lim[:, 0], lim[:, 1], size=(4000, world.dof))
    hit = set()
    for q in qs:
        hit.update(world.check(q).pairs)
    assert not hit & set(r.proven)
    assert hit, "the sample must reach some collisions for this check to mean anything"


def test_proof_is_cached_by_content(tmp_path):
    from arduinobot.planner.collision.acm_proof import proven_never_pairs
    from arduinobot.planner.collision.world import CollisionWorld
    from arduinobot.service.process.disk_cache import DiskCache
    world = CollisionWorld(_no_srdf(load_description()))
    cache = DiskCache(tmp_path)
    first = proven_never_pairs(world, cache=cache)
    files = list((tmp_path / "never-pairs").glob("*.npz"))
    assert len(files) == 1
    assert proven_never_pairs(world, cache=cache) == first
    # another margin is another content key: computed anew, not read
    proven_never_pairs(world, cache=cache, margin=0.05)
    assert len(list((tmp_path / "never-pairs").glob("*.npz"))) == 2
    # a cache folder that cannot be written costs the speed-up only
    ro = tmp_path / "file-not-dir"
    ro.write_text("x")
    assert proven_never_pairs(world, cache=DiskCache(ro)) == first


def test_planner_without_srdf_skips_only_adjacent_and_proven_pairs():
    from arduinobot.planner.planning.pipeline import MotionPlanner
    mp = MotionPlanner(_no_srdf(load_description()))
    world = mp.world(())
    reasons = {e.reason for e in world.acm}
    assert reasons == {"Adjacent", "Never-proven", "Ground"}
    # the ground's allowance is only the links that never move standing on it
    on_ground = {(e.link1, e.link2) for e in world.acm if e.reason == "Ground"}
    statics = {n for n, still in zip(world.bodies.names, world.bodies.statics) if still}
    assert on_ground and all("ground" in p and set(p) - {"ground"} <= statics
                             for p in on_ground), on_ground


def test_sampled_pairs_are_written_but_never_skipped():
    d = load_description()
    r = compute_acm(d, samples=200, seed=1, include_sampled=True)
    sampled = [p for p in r.disabled if p.reason == "Never-sampled"]
    assert sampled and {(p.link1, p.link2) for p in sampled} == set(r.unproven)
    from dataclasses import replace
    srdf = replace(d.srdf, disabled_collisions=r.disabled)
    acm = AllowedCollisionMatrix.from_srdf(srdf)
    assert not any(acm.allowed(p.link1, p.link2) for p in sampled)
