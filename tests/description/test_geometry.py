"""src/arduinobot/description/geometry.py: a URDF link's geometry is a scene shape (a
box, sphere or cylinder of arduinobot.scene.shapes, or a MeshFile), so the triangles,
the MuJoCo geom and the mesh check ask the shape."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from arduinobot.description import MeshFile, MeshNotFound
from arduinobot.description.meshes import shape_mesh
from arduinobot.description.model import Origin, Shape
from arduinobot.description.packages import build_package_index
from arduinobot.description.urdf import parse_urdf
from arduinobot.scene.shapes import Box, Cylinder, Sphere

URDF = """<robot name="r">
  <link name="base">
    <collision><origin xyz="0 0 1"/><geometry><box size="0.1 0.2 0.3"/></geometry></collision>
    <collision><geometry><sphere radius="0.05"/></geometry></collision>
    <collision><geometry><cylinder radius="0.04" length="0.5"/></geometry></collision>
    <visual><geometry><mesh filename="{mesh}" scale="0.01 0.01 0.01"/></geometry></visual>
    <visual><geometry><box size="0 0 0"/></geometry></visual>
  </link>
</robot>"""


@pytest.fixture
def robot(tmp_path):
    stl = tmp_path / "block.stl"
    trimesh.creation.box(extents=(20.0, 40.0, 60.0)).export(stl)
    report = parse_urdf(URDF.format(mesh=stl), packages=build_package_index([], env={}),
                        source=tmp_path / "r.urdf")
    assert report.robot is not None and not report.problems
    return report.robot, stl


def test_a_urdf_primitive_is_the_scenes_shape(robot):
    r, stl = robot
    base = r.links["base"]
    assert [s.geometry for s in base.collisions] == [Box((0.1, 0.2, 0.3)), Sphere(0.05),
                                                     Cylinder(0.04, 0.5)]
    assert base.collisions[2].geometry.mjcf() == ("cylinder", "0.04 0.25")
    # as written: a zero box is the check's to report, not the reader's to refuse
    assert base.visuals[1].geometry == Box((0.0, 0.0, 0.0))
    mesh = base.visuals[0].geometry
    assert mesh == MeshFile(str(stl), stl.resolve(), (0.01, 0.01, 0.01))
    assert mesh.mjcf() is None and mesh.source == stl.resolve()
    assert mesh.source_scale == (0.01, 0.01, 0.01) and Box((1, 1, 1)).source_scale == (1, 1, 1)


def test_shape_mesh_places_each_kind_in_its_link(robot):
    r, _ = robot
    base = r.links["base"]
    lo, hi = shape_mesh(base.collisions[0]).bounds
    assert np.allclose(lo, [-0.05, -0.1, 0.85]) and np.allclose(hi, [0.05, 0.1, 1.15])
    lo, hi = shape_mesh(base.visuals[0]).bounds  # the file's 20 x 40 x 60 at 0.01
    assert np.allclose(hi - lo, [0.2, 0.4, 0.6])
    assert shape_mesh(base.collisions[1]).bounds[1] == pytest.approx([0.05] * 3, rel=1e-3)


def test_an_unresolved_mesh_names_its_uri_and_the_element():
    s = Shape(Origin(), MeshFile("package://nowhere/a.stl"))
    assert s.geometry.source is None and s.geometry.mjcf() is None
    with pytest.raises(MeshNotFound) as e:
        shape_mesh(s, element="link 'base' visual")
    assert e.value.element == "link 'base' visual" and "package://nowhere/a.stl" in str(e.value)
