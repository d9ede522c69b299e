"""The body table (kinds, pairs, frozen) and the certifier's resume protocol."""

import numpy as np
import pytest

from arduinobot.description import load_description
from arduinobot.planner.collision.proof.certify import Certifier
from arduinobot.planner.collision.proof.resume import WALK, Status, Stop, new_walk
from arduinobot.planner.collision.table import BodyKind, BodyTable, checked_kinds, place_carried
from arduinobot.planner.collision.world import CollisionWorld
from arduinobot.scene.obstacles import Obstacle


@pytest.fixture(scope="module")
def world():
    return CollisionWorld(load_description(), obstacles=[
        Obstacle("table", "box", size=(0.6, 1.2, 0.05), xyz=(0, 1.0, 0.6)),
        Obstacle("ball", "sphere", radius=0.05, xyz=(0.5, 0.5, 0.5))])


def test_every_body_has_its_kind_and_obstacles_sit_where_the_scene_puts_them(world):
    t = world.table
    links = t.of_kind(BodyKind.LINK)
    assert [t.names[b] for b in links] == list(world.bodies.names) == list(world.link_bodies)
    assert [t.names[b] for b in t.of_kind(BodyKind.OBSTACLE)] == ["table", "ball"]
    assert t.of_kind(BodyKind.CARRIED) == ()
    for b in t.of_kind(BodyKind.OBSTACLE):
        assert t.bodies.frame[b] == -1
        o = world.obstacles[b - len(links)]
        assert np.array_equal(t.bodies.pose[b], o.pose())
    for b in links:
        assert world.kin.link_names[t.bodies.frame[b]] == t.names[b]


def test_pairs_are_checked_by_kind_and_matrix_never_obstacle_with_obstacle(world):
    t = world.table
    kinds = {t.pair_kinds(p) for p in range(len(t.pair_names))}
    assert (BodyKind.OBSTACLE, BodyKind.OBSTACLE) not in kinds
    assert (BodyKind.LINK, BodyKind.OBSTACLE) in kinds and (BodyKind.LINK, BodyKind.LINK) in kinds
    assert not checked_kinds(BodyKind.OBSTACLE, BodyKind.OBSTACLE)
    assert checked_kinds(BodyKind.CARRIED, BodyKind.OBSTACLE)
    assert checked_kinds(BodyKind.CARRIED, BodyKind.CARRIED)
    for (a, b), (na, nb) in zip(t.pairs.index, t.pair_names):
        assert (t.names[a], t.names[b]) == (na, nb)
        assert not world.acm.allowed(na, nb)
    assert t.pairs.weight.shape == (len(t.pair_names), world.dof)
    # every link moves relative to a static obstacle by itself
    for p in range(len(t.pair_names)):
        ka, kb = t.pair_kinds(p)
        a, b = t.pairs.index[p]
        if ka == BodyKind.LINK and kb == BodyKind.OBSTACLE:
            assert t.pairs.mover[p] == a


def test_the_table_is_frozen(world):
    t = world.table
    with pytest.raises(ValueError):
        t.bodies.pose[0, 0, 0] = 2.0
    with pytest.raises(ValueError):
        t.pairs.weight[0, 0] = 0.0
    with pytest.raises(AttributeError):
        t.names = ()  # type: ignore[misc]


def test_build_refuses_a_body_whose_link_contradicts_its_kind():
    eye = np.tile(np.eye(4), (2, 1, 1))
    none = np.zeros((0, 2), np.int64)
    with pytest.raises(ValueError, match="OBSTACLE"):
        BodyTable.build(["a", "b"], [BodyKind.LINK, BodyKind.OBSTACLE], [1, 2], eye, none,
                        np.zeros((0, 1)), np.zeros(0, np.int64), n_links=3)
    with pytest.raises(ValueError, match="CARRIED"):
        BodyTable.build(["a", "b"], [BodyKind.LINK, BodyKind.CARRIED], [1, -1], eye, none,
                        np.zeros((0, 1)), np.zeros(0, np.int64), n_links=3)


def test_a_carried_body_gets_a_pose_slot_of_its_link_times_its_offset():
    rng = np.random.default_rng(4)
    offset = np.eye(4)
    offset[:3, 3] = (0.0, 0.0, 0.12)
    poses = np.tile(np.eye(4), (4, 1, 1))  # 3 links + the box's slot
    for k in range(3):
        poses[k, :3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        poses[k, :3, 3] = rng.normal(size=3)
    table = BodyTable.build(["l1", "box", "wall"],
                            [BodyKind.LINK, BodyKind.CARRIED, BodyKind.OBSTACLE], [1, 2, -1],
                            np.stack([np.eye(4), offset, np.eye(4)]),
                            np.array([[0, 1], [1, 2]]), np.ones((2, 1)), np.array([-1, 1]),
                            n_links=3)
    b = table.bodies
    assert list(b.frame) == [1, 3, -1] and list(b.link) == [1, 2, -1]
    assert list(b.carried) == [1] and table.slots == 4
    assert table.pair_kinds(1) == (BodyKind.CARRIED, BodyKind.OBSTACLE)
    place_carried(b.frame, b.link, b.pose, b.carried, poses)
    assert np.allclose(poses[3], poses[2] @ offset, atol=1e-15)


def test_the_walk_record_round_trips_and_the_status_is_an_int():
    rec = new_walk()
    assert rec.dtype == WALK and rec[0]["injected"] == -1.0
    rec[0]["pair"], rec[0]["piece"], rec[0]["sigma"], rec[0]["bounds"] = 3, 2, 0.25, 17
    assert Stop.read(rec) == Stop(pair=3, piece=2, sigma=0.25, bounds=17)
    assert [int(s) for s in Status] == [0, 1, 2]


def test_a_certificate_counts_the_bounds_its_walk_recorded(world):
    # a motion past the table: resumed walks (hull or exact queries) carry the count on
    lim = world.description.robot.position_limits()
    rng = np.random.default_rng(2)
    free = [q for q in rng.uniform(lim[:, 0], lim[:, 1], size=(200, 4)) if world.is_valid(q)]
    certs = [Certifier(world, fraction=0.5).path(np.array([a, b]))
             for a, b in zip(free[:20:2], free[1:20:2])]
    assert any(c.free for c in certs)
    for c in certs:
        assert c.bounds > 0 or not c.free
        if c.free:
            assert c.certified_clearance >= world.padding
