"""src/arduinobot/scene/shapes/: each shape reads back what it writes, keys equal shapes
alike, gives the closed-form inertia of its solid, and names the field that is wrong."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
import trimesh

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.obstacles import Obstacle
from arduinobot.scene.shapes import Box, Cylinder, Mesh, Sphere, kinds, shape_class


@pytest.fixture
def stl(tmp_path):
    path = tmp_path / "block.stl"
    trimesh.creation.box(extents=(0.2, 0.4, 0.6)).export(path)
    return str(path)


def _shapes(stl: str):
    return [Box((0.1, 0.2, 0.3)), Sphere(0.05), Cylinder(0.04, 0.5), Mesh(stl)]


def test_every_kind_is_registered_under_its_json_name():
    assert kinds() == ("box", "sphere", "cylinder", "mesh")
    assert [shape_class(k).kind for k in kinds()] == list(kinds())


def test_json_round_trips_and_keys_equal_for_equal_shapes(stl):
    for s in _shapes(stl):
        data = s.to_json()
        back = shape_class(s.kind).from_json(data, where="o")
        assert back == s and back.key() == s.key() and back.content_key() == s.content_key()
        o = Obstacle("o", s, xyz=(1.0, 2.0, 3.0), rpy=(0.1, 0.2, 0.3))
        wire = o.to_json()
        assert wire["shape"] == s.kind and Obstacle.from_mapping(wire) == o
        assert pickle.loads(pickle.dumps(o)) == o
        assert dataclasses.replace(o, xyz=(0.0, 0.0, 0.0)).geometry == s
    # ints and floats, tuples and lists: the same shape
    assert Box.from_json({"size": [1, 2, 3]}, where="o").key() == Box((1.0, 2.0, 3.0)).key()
    assert Box((1.0, 2.0, 3.0)).key() != Box((1.0, 2.0, 3.5)).key()
    assert Sphere(0.1).key() != Cylinder(0.1, 0.1).key()


def test_a_mesh_key_is_its_content(stl, tmp_path):
    copy = tmp_path / "copy.stl"
    copy.write_bytes(open(stl, "rb").read())
    a, b = Mesh(stl), Mesh(str(copy))
    assert a.key() != b.key() and a.content_key() == b.content_key()


def test_unit_inertia_matches_the_closed_forms():
    c, i = Box((0.1, 0.2, 0.3)).unit_inertia()
    assert np.allclose(c, 0) and np.allclose(
        i, np.diag([0.2**2 + 0.3**2, 0.1**2 + 0.3**2, 0.1**2 + 0.2**2]) / 12)
    _, i = Sphere(0.05).unit_inertia()
    assert np.allclose(i, np.eye(3) * 2 / 5 * 0.05**2)
    r, h = 0.04, 0.5
    _, i = Cylinder(r, h).unit_inertia()
    assert np.allclose(i, np.diag([(3 * r**2 + h**2) / 12, (3 * r**2 + h**2) / 12, r**2 / 2]))


def test_a_closed_mesh_has_its_solid_s_inertia(stl):
    c, i = Mesh(stl).unit_inertia()
    assert np.allclose(c, 0, atol=1e-12)
    assert np.allclose(i, Box((0.2, 0.4, 0.6)).unit_inertia()[1])


def test_reach_is_the_farthest_surface_point(stl):
    assert Box((0.1, 0.2, 0.3)).reach() == pytest.approx(0.5 * np.sqrt(0.14))
    assert Sphere(0.05).reach() == 0.05
    assert Cylinder(0.04, 0.5).reach() == pytest.approx(np.hypot(0.04, 0.25))
    assert Mesh(stl).reach() == pytest.approx(0.5 * np.sqrt(0.56))  # a corner of its box
    for s in _shapes(stl):  # its triangles' farthest vertex is on it
        d = np.linalg.norm(s.triangles().vertices, axis=1)
        assert d.max() == pytest.approx(s.reach())
    assert all(s.source_scale == (1.0, 1.0, 1.0) for s in _shapes(stl))


def test_triangles_hold_the_shape(stl):
    for s in _shapes(stl):
        m = s.triangles()
        assert len(m.faces) > 0 and m.is_watertight
        half = s.half_extents()
        if half is not None:  # the box tree's box holds every vertex
            assert np.all(np.abs(m.vertices) <= half + 1e-12)


@pytest.mark.parametrize(("kind", "data", "field"), [
    ("box", {"size": [1, 0, 1]}, "obstacles[2].size"),
    ("box", {}, "obstacles[2].size"),
    ("sphere", {"radius": -1}, "obstacles[2].radius"),
    ("cylinder", {"radius": 0.1, "length": "long"}, "obstacles[2].length"),
    ("mesh", {"mesh_path": "/nowhere.stl"}, "obstacles[2].mesh_path"),
    ("sphere", {"radius": 1, "size": [1, 1, 1]}, "obstacles[2]"),
])
def test_a_bad_field_is_named(kind, data, field):
    with pytest.raises(InvalidRequest) as e:
        shape_class(kind).from_json(data, where="obstacles[2]")
    assert e.value.field == field
    with pytest.raises(InvalidRequest) as e:
        Obstacle.from_mapping({"id": "o", "shape": kind, **data}, where="obstacles[2]")
    assert e.value.field == field


def test_an_unknown_kind_is_named():
    with pytest.raises(InvalidRequest) as e:
        shape_class("cone", field="obstacles[0].shape")
    assert e.value.field == "obstacles[0].shape" and "box" in str(e.value)


def test_numbers_of_the_command_line():
    assert Cylinder.from_numbers([0.1, 2.0], where="o") == Cylinder(0.1, 2.0)
    with pytest.raises(InvalidRequest) as e:
        Box.from_numbers([1.0, 1.0], where="o")
    assert e.value.field == "o"
    with pytest.raises(InvalidRequest) as e:
        Mesh.from_numbers([1.0], where="o")
    assert e.value.field == "o.shape"


def test_an_inline_field_belongs_to_its_shape_alone(tmp_path):
    from arduinobot.scene.shapes import check_inline

    with pytest.raises(InvalidRequest) as e:
        check_inline(Sphere, {"shape": "sphere", "radius": 1, "scale": [1, 1, 1]}, where="add[0]")
    assert e.value.field == "add[0].scale" and "only a mesh object" in str(e.value)
    check_inline(Mesh, {"mesh": {}, "scale": 1}, where="add[0]")  # its own: no refusal
    assert Box.stored({"size": [1, 1, 1]}, where="add[0]", folder=tmp_path) == {"size": [1, 1, 1]}
    with pytest.raises(InvalidRequest) as e:
        Mesh.stored({}, where="add[0]", folder=tmp_path)
    assert e.value.field == "add[0].mesh"


def test_a_listing_reads_each_shape_s_dimensions_from_its_wire_form():
    assert Box.summary({"size": [1, 1, 0.1]}) == "size 1,1,0.1"
    assert Cylinder.summary({"radius": 0.1, "length": 2}) == "radius 0.1 length 2"
    assert Mesh.summary({"mesh": {"format": "stl", "data": "YWJjZA=="}, "scale": 0.001}) \
        == "stl mesh, 4 bytes, scale 0.001"


def test_a_shape_grows_and_shrinks_by_a_margin_on_every_side():
    from arduinobot.scene.shapes import Box, Cylinder, Sphere
    assert Box((0.1, 0.2, 0.3)).grown(0.01).size == pytest.approx((0.12, 0.22, 0.32))
    assert Sphere(0.05).grown(-0.01).radius == pytest.approx(0.04)
    c = Cylinder(0.05, 0.2).grown(0.01)
    assert (c.radius, c.length) == pytest.approx((0.06, 0.22))
    with pytest.raises(InvalidRequest, match="> 0"):
        Box((0.1, 0.2, 0.3)).grown(-0.06)  # shrunk to nothing is refused, not flipped


def test_a_shape_says_which_points_lie_inside_it_grown_by_a_padding():
    from arduinobot.scene.shapes import Box, Cylinder, Sphere
    pts = np.array([[0.0, 0.0, 0.0], [0.06, 0.0, 0.0], [0.0, 0.0, 0.12], [0.2, 0.2, 0.2]])
    assert Box((0.1, 0.1, 0.2)).contains(pts).tolist() == [True, False, False, False]
    assert Box((0.1, 0.1, 0.2)).contains(pts, 0.02).tolist() == [True, True, True, False]
    assert Sphere(0.05).contains(pts, 0.011).tolist() == [True, True, False, False]
    assert Cylinder(0.05, 0.2).contains(pts).tolist() == [True, False, False, False]
