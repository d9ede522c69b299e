import fcl
import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import load_description
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.obstacles import Obstacle
from tests.helpers.fcl_bodies import fcl_objects, place


@pytest.fixture(scope="module")
def world(desc):
    return CollisionWorld(desc, obstacles=[Obstacle("table", "box", size=(0.6, 1.2, 0.05),
                                                    xyz=(0, 1.0, 0.6))])


def _brute(w, q):
    poses = w.kin.link_poses(q)
    objs = fcl_objects(w)
    hits = set()
    for (a, b), nm in zip(w.table.pairs.index, w.pair_names):
        place(w, objs, poses, a, b)
        if fcl.collide(objs[a], objs[b], fcl.CollisionRequest(), fcl.CollisionResult()):
            hits.add(nm)
    return hits


def test_broad_phase_never_hides_a_collision(world, desc):
    lim = desc.robot.position_limits()
    qs = np.random.default_rng(3).uniform(lim[:, 0], lim[:, 1], size=(300, 4))
    n_hit = 0
    for q in qs:
        expect = _brute(world, q)
        assert set(world.check(q).pairs) == expect
        assert world.is_valid(q) == (not expect)
        n_hit += bool(expect)
    assert 0 < n_hit < len(qs)


def test_first_invalid_and_obstacle_pair(world):
    free = np.zeros(4)
    blocked = np.array([0.0, -0.75, -0.75, 0.0])
    chk = world.check(blocked, clearance=True)
    assert not chk.valid and any("table" in p for p in chk.pairs) and chk.clearance == 0.0
    qs = np.linspace(free, blocked, 50)
    i = world.first_invalid(qs)
    assert i > 0 and not world.is_valid(qs[i]) and world.is_valid(qs[i - 1])
    assert world.first_invalid(qs[:i]) == -1


def test_clearance_and_padding(desc):
    w = CollisionWorld(desc)
    c = w.check(np.zeros(4), clearance=True)
    assert c.valid and 0 < c.clearance < 0.05 and c.closest is not None
    d_min, pair = w.min_clearance(np.zeros((2, 4)))
    assert d_min == pytest.approx(c.clearance)
    padded = CollisionWorld(desc, padding=c.clearance + 0.005)
    assert not padded.is_valid(np.zeros(4))
    with pytest.raises(InvalidRequest):
        CollisionWorld(desc, padding=-1)


def test_link_trees_are_cached_by_content(tmp_path):
    import numpy as np

    from arduinobot.planner.collision.world import CollisionWorld
    from arduinobot.service.process.disk_cache import DiskCache
    d = load_description()
    first = CollisionWorld(d, cache=DiskCache(tmp_path))
    files = sorted((tmp_path / "obb-tree").glob("*.npz"))
    assert len(files) == len(first.link_bodies)
    again = CollisionWorld(d, cache=DiskCache(tmp_path))
    for a, b in zip(first.bodies.trees, again.bodies.trees):
        for k in ("center", "axes", "half", "left", "right"):
            assert np.array_equal(getattr(a, k), getattr(b, k))
    assert sorted((tmp_path / "obb-tree").glob("*.npz")) == files
    q = np.array([0.3, 0.5, -0.2, -0.4])
    assert again.check(q) == first.check(q)


def test_without_narrow_phase_a_world_is_conservative(desc):
    # trees alone: never accepts a state the exact world refuses (at its padding), and
    # refuses some free ones near contact - the price of asking no FCL
    lim = desc.robot.position_limits()
    qs = np.random.default_rng(5).uniform(lim[:, 0], lim[:, 1], size=(300, 4))
    for pad in (0.0, 0.002):
        exact = CollisionWorld(desc, padding=pad)
        trees = exact.with_scene((), narrow_phase=False)
        assert not trees.narrow_phase and trees.padding == pad
        verdicts = [(exact.is_valid(q), trees.is_valid(q)) for q in qs]
        assert not any(t and not e for e, t in verdicts)
        assert any(e and not t for e, t in verdicts)
        assert any(t for _, t in verdicts)
        i = trees.first_invalid(qs)
        assert i == next(k for k, (_, t) in enumerate(verdicts) if not t)


def test_pair_distance_to_a_box_is_fcl_distance_to_the_solid_box_at_free_states(desc):
    # the box is measured by its surface (faster): at a free state that is the distance
    # to the solid box FCL's primitive gives
    w = CollisionWorld(desc, obstacles=[Obstacle("table", "box", size=(0.6, 1.2, 0.05),
                                              xyz=(0.3, 0.6, 1.0), rpy=(0.2, 0, 0.4))])
    lim = desc.robot.position_limits()
    box = next(p for p, (_, b) in enumerate(w.pair_names) if b == "table")
    a, b = w.table.pairs.index[box]
    objs = fcl_objects(w)
    compared = 0
    for q in np.random.default_rng(3).uniform(lim[:, 0], lim[:, 1], size=(60, 4)):
        if not w.is_valid(q):
            continue
        got = w.pair_distance(q, box)
        place(w, objs, w.kin.link_poses(q), a)
        solid = fcl.distance(objs[a], objs[b], fcl.DistanceRequest(),
                             fcl.DistanceResult())
        assert got == pytest.approx(max(solid, 0.0), abs=1e-9)
        compared += got < 0.2
    assert compared > 5


def test_lower_bound_never_exceeds_the_exact_distance(world, desc):
    lim = desc.robot.position_limits()
    qs = np.random.default_rng(8).uniform(lim[:, 0], lim[:, 1], size=(100, 4))
    positive = 0
    for q in qs:
        lb = world.lower_bound(q)
        exact = min(world.pair_distance(q, p) for p in range(len(world.pair_names)))
        assert lb <= exact + 1e-12
        positive += lb > 0
    assert positive > 0


def test_scene_meshes_are_built_once_per_content_across_worlds(world, tmp_path, monkeypatch):
    import trimesh

    from arduinobot.planner.collision import assembly

    built: list[str] = []
    real = assembly._build_geometry

    def counting(o):
        built.append(o.id)
        return real(o)

    monkeypatch.setattr(assembly, "_build_geometry", counting)
    path = tmp_path / "bin.stl"
    path.write_bytes(trimesh.creation.box(extents=(0.3, 0.3, 0.3)).export(file_type="stl"))
    # the box sits where the upper arm stands at q = 0
    mesh = Obstacle("bin", "mesh", mesh_path=str(path), xyz=(0.0, 0.0, 1.0))
    ball = Obstacle("ball", "sphere", radius=0.05, xyz=(2.0, 2.0, 2.0))
    a = world.with_scene([mesh])
    b = world.with_scene([mesh, ball])  # the scene's next revision: one more object
    c = world.with_scene([Obstacle("bin2", "mesh", mesh_path=str(path), xyz=(0, 0, 1))])
    assert built == ["bin", "ball"]  # the same content, under any id, is built once
    q0 = np.zeros(a.kin.dof)
    for w, name in ((a, "bin"), (b, "bin"), (c, "bin2")):
        assert ("forward_drive_arm", name) in w.check(q0).pairs
    assert b.check(q0).pairs == a.check(q0).pairs
    # the same file rewritten with other content is another shape: built again, and a
    # tiny box where the big one stood collides with nothing
    path.write_bytes(trimesh.creation.box(extents=(0.001, 0.001, 0.001)).export(
        file_type="stl"))
    d = world.with_scene([Obstacle("bin", "mesh", mesh_path=str(path), xyz=(0.5, 0.5, 0))])
    assert built == ["bin", "ball", "bin"]
    assert d.check(q0).valid
