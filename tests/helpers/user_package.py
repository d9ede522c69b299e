"""Build a user's own description package, unlike ours in every way that matters:
another name, other links and joints, millimetre meshes, a large STL, xacro args, and
$(find) / package:// / relative / file:// references."""

from __future__ import annotations

from pathlib import Path

import trimesh

PACKAGE = "my_bot_description"


def make_user_package(root: Path, *, fine_faces: int = 60_000) -> Path:
    """Write the package under ``root`` and return its folder."""
    pkg = root / PACKAGE
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "meshes").mkdir()
    (pkg / "config").mkdir()
    (pkg / "package.xml").write_text(
        f'<?xml version="1.0"?><package format="3"><name>{PACKAGE}</name>'
        "<version>1.0.0</version><description>test</description>"
        '<maintainer email="a@b.c">me</maintainer><license>MIT</license></package>')
    # millimetres: a 200 x 100 x 50 mm base, a finely tessellated 80 mm sphere
    trimesh.creation.box(extents=(200.0, 100.0, 50.0)).export(pkg / "meshes" / "base.stl")
    sphere = trimesh.creation.icosphere(subdivisions=7, radius=40.0)
    while len(sphere.faces) < fine_faces:
        sphere = sphere.subdivide()
    sphere.export(pkg / "meshes" / "head.stl")
    trimesh.creation.cylinder(radius=15.0, height=300.0, sections=64).export(
        pkg / "meshes" / "arm.stl")
    (pkg / "urdf" / "common.xacro").write_text(
        '<robot xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:macro name="inertia" params="m"><inertial><mass value="${m}"/>'
        '<inertia ixx="${m*0.01}" ixy="0" ixz="0" iyy="${m*0.01}" iyz="0" izz="${m*0.01}"/>'
        "</inertial></xacro:macro></robot>")
    arm_uri = (pkg / "meshes" / "arm.stl").as_uri()
    (pkg / "urdf" / "my_bot.urdf.xacro").write_text(f"""<?xml version="1.0"?>
<robot name="my_bot" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="reach" default="0.5"/>
  <xacro:arg name="prefix" default=""/>
  <xacro:include filename="$(find {PACKAGE})/urdf/common.xacro"/>
  <link name="$(arg prefix)base">
    <xacro:inertia m="2.0"/>
    <visual><geometry><mesh filename="package://{PACKAGE}/meshes/base.stl" scale="0.001 0.001 0.001"/></geometry></visual>
    <collision><geometry><mesh filename="package://{PACKAGE}/meshes/base.stl" scale="0.001 0.001 0.001"/></geometry></collision>
  </link>
  <link name="$(arg prefix)arm">
    <xacro:inertia m="0.5"/>
    <visual><origin xyz="0 0 0.15"/><geometry><mesh filename="{arm_uri}" scale="0.001 0.001 0.001"/></geometry></visual>
    <collision><origin xyz="0 0 0.15"/><geometry><mesh filename="{arm_uri}" scale="0.001 0.001 0.001"/></geometry></collision>
  </link>
  <link name="$(arg prefix)head">
    <xacro:inertia m="0.3"/>
    <visual><geometry><mesh filename="../meshes/head.stl" scale="0.001 0.001 0.001"/></geometry></visual>
    <collision><geometry><mesh filename="../meshes/head.stl" scale="0.001 0.001 0.001"/></geometry></collision>
  </link>
  <joint name="$(arg prefix)swing" type="revolute">
    <parent link="$(arg prefix)base"/><child link="$(arg prefix)arm"/>
    <origin xyz="0 0 0.025"/><axis xyz="0 1 0"/>
    <limit lower="-1.0" upper="1.0" effort="5" velocity="2"/>
  </joint>
  <joint name="$(arg prefix)lift" type="prismatic">
    <parent link="$(arg prefix)arm"/><child link="$(arg prefix)head"/>
    <origin xyz="0 0 $(arg reach)"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.2" effort="50" velocity="0.5"/>
  </joint>
</robot>
""")
    return pkg
