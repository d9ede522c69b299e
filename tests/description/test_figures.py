"""The shipped model carries every name and figure of shared/robot-model.md."""

from __future__ import annotations

import math

import pytest
from lxml import etree

from arduinobot.description import DEFAULT_MODEL

PI = 3.14159
XACRO_NS = "{http://www.ros.org/wiki/xacro}"

# link -> (mesh file, mass, visual/collision xyz, rpy), from robot-model.md
LINKS = {
    "base_link": ("basement.STL", 1.0, (-0.5, -0.5, 0), (0, 0, 0)),
    "base_plate": ("base_plate.STL", 0.1, (-0.39, -0.39, -0.56), (0, 0, 0)),
    "forward_drive_arm": ("forward_drive_arm.STL", 0.1, (0.19, 0.06, -0.08), (0, -PI / 2, PI / 2)),
    "horizontal_arm": ("horizontal_arm.STL", 0.1, (-0.03, -0.4, -0.06), (PI / 2, 0, PI / 2)),
    "claw_support": ("claw_support.STL", 0.05, (0, -0.05, -0.15), (0, 0, PI / 2)),
    "gripper_right": ("right_finger.STL", 0.01, (-0.1, 0.50, -0.1), (0, 0, -PI / 2)),
    "gripper_left": ("left_finger.STL", 0.01, (-0.04, 0.50, -0.1), (0, 0, -PI / 2)),
}
# joint -> (type, parent, child, xyz, axis, lower, upper)
JOINTS = {
    "virtual_joint": ("fixed", "world", "base_link", (0, 0, 0), None, None, None),
    "joint_1": ("revolute", "base_link", "base_plate", (0, 0, 0.307), (0, 0, 1), -PI / 2, PI / 2),
    "joint_2": ("revolute", "base_plate", "forward_drive_arm", (-0.02, 0, 0.35), (1, 0, 0),
                -PI / 2, PI / 2),
    "joint_3": ("revolute", "forward_drive_arm", "horizontal_arm", (0, 0, 0.8), (1, 0, 0),
                -PI / 2, PI / 2),
    "horizontal_arm_to_claw_support": ("fixed", "horizontal_arm", "claw_support", (0, 0.82, 0),
                                       None, None, None),
    "joint_4": ("revolute", "claw_support", "gripper_right", (-0.04, 0.13, -0.1), (0, 0, 1),
                -PI / 2, 0),
    "joint_5": ("revolute", "claw_support", "gripper_left", (-0.22, 0.13, -0.1), (0, 0, 1),
                0, PI / 2),
}


@pytest.fixture
def robot(desc):
    return desc.robot


def test_robot_name_and_sets(robot):
    assert robot.name == "arduinobot"
    assert set(robot.links) == {"world", *LINKS}
    assert set(robot.joints) == set(JOINTS)
    assert robot.root == "world"
    assert robot.actuated_joints == ("joint_1", "joint_2", "joint_3", "joint_4")


@pytest.mark.parametrize("name", sorted(LINKS))
def test_link_figures(robot, name):
    mesh, mass, xyz, rpy = LINKS[name]
    link = robot.links[name]
    assert link.inertial is not None
    assert link.inertial.mass == pytest.approx(mass, abs=1e-12)
    ine = link.inertial
    assert (ine.ixx, ine.ixy, ine.ixz, ine.iyy, ine.iyz, ine.izz) == (1.0, 0.0, 0.0, 1.0, 0.0, 1.0)
    assert len(link.visuals) == 1 and len(link.collisions) == 1
    for shape in (link.visuals[0], link.collisions[0]):
        g = shape.geometry
        assert g.kind == "mesh"
        assert g.uri == f"package://arduinobot_description/meshes/{mesh}"
        assert g.scale == (0.01, 0.01, 0.01)
        assert shape.origin.xyz == pytest.approx(xyz, abs=1e-9)
        assert shape.origin.rpy == pytest.approx(rpy, abs=1e-9)
        assert g.path is not None and g.path.is_file()


def test_world_is_bare(robot):
    w = robot.links["world"]
    assert w.inertial is None and not w.visuals and not w.collisions


@pytest.mark.parametrize("name", sorted(JOINTS))
def test_joint_figures(robot, name):
    jtype, parent, child, xyz, axis, lower, upper = JOINTS[name]
    j = robot.joints[name]
    assert (j.type, j.parent, j.child) == (jtype, parent, child)
    assert j.origin.xyz == pytest.approx(xyz, abs=1e-12)
    assert j.origin.rpy == (0, 0, 0)
    if jtype == "revolute":
        assert j.axis == pytest.approx(axis)
        assert j.limit is not None
        assert j.limit.lower == pytest.approx(lower, abs=1e-9)
        assert j.limit.upper == pytest.approx(upper, abs=1e-9)
        assert j.limit.effort == 30.0 and j.limit.velocity == 10.0


def test_mimic(robot):
    m = robot.joints["joint_5"].mimic
    assert m is not None and m.joint == "joint_4" and m.multiplier == -1.0 and m.offset == 0.0
    assert robot.mimic_joints == ("joint_5",)


def test_xacro_source_uses_properties_and_macro():
    root = etree.parse(str(DEFAULT_MODEL)).getroot()
    props = {p.get("name"): p.get("value") for p in root.iter(f"{XACRO_NS}property")}
    assert props == {"PI": "3.14159", "effort": "30.0", "velocity": "10.0"}
    macros = {m.get("name"): m.get("params") for m in root.iter(f"{XACRO_NS}macro")}
    assert macros == {"default_inertial": "mass"}
    calls = [c.get("mass") for c in root.iter(f"{XACRO_NS}default_inertial")]
    assert sorted(map(float, calls)) == sorted(v[1] for v in LINKS.values())
    for lim in root.iter("limit"):
        assert lim.get("effort") == "${effort}" and lim.get("velocity") == "${velocity}"
    assert math.isclose(float(props["PI"]), PI)


def test_ros_package_files():
    pkg = DEFAULT_MODEL.parent.parent
    manifest = etree.parse(str(pkg / "package.xml")).getroot()
    assert manifest.findtext("name") == "arduinobot_description"
    assert manifest.findtext("export/build_type") == "ament_cmake"
    cmake = (pkg / "CMakeLists.txt").read_text()
    assert "project(arduinobot_description)" in cmake
    assert "DIRECTORY meshes urdf" in cmake and "share/${PROJECT_NAME}" in cmake
