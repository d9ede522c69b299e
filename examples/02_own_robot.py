"""Your own robot: a package of your own, its xacro and its `package://` meshes.

This writes a small ROS 2 description package (millimetre STL meshes as CAD tools export
them, a xacro argument), checks it as `arduinobot check` does, loads it and plans on it
in this process, as `arduinobot plan --local` and `arduinobot serve` would. With your
own package, start at `check_model`; on the command line:

    arduinobot check  WS/src/my_arm_description/urdf/my_arm.urdf.xacro --package-dir WS/src
    arduinobot serve  WS/src/my_arm_description/urdf/my_arm.urdf.xacro --package-dir WS/src

    .venv/bin/python examples/02_own_robot.py [OUT_DIR]   # default: a temporary folder
"""

import sys
import tempfile
from pathlib import Path

import trimesh

from arduinobot.description import load_description
from arduinobot.description.checks import check_model
from arduinobot.service.local import LocalService

PACKAGE = "my_arm_description"
XACRO = f"""<?xml version="1.0"?>
<robot name="my_arm" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="reach" default="0.3"/>
  <xacro:macro name="part" params="name mesh mass z">
    <link name="${{name}}">
      <inertial><origin xyz="0 0 ${{z}}"/><mass value="${{mass}}"/>
        <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.001"/></inertial>
      <visual><geometry>
        <mesh filename="package://{PACKAGE}/meshes/${{mesh}}.stl" scale="0.001 0.001 0.001"/>
      </geometry></visual>
      <collision><geometry>
        <mesh filename="package://{PACKAGE}/meshes/${{mesh}}.stl" scale="0.001 0.001 0.001"/>
      </geometry></collision>
    </link>
  </xacro:macro>
  <xacro:part name="base" mesh="base" mass="1.0" z="0.025"/>
  <xacro:part name="upper" mesh="link" mass="0.3" z="0.15"/>
  <xacro:part name="fore" mesh="link" mass="0.2" z="0.15"/>
  <joint name="yaw" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.06"/><axis xyz="0 0 1"/>
    <limit lower="-3.0" upper="3.0" effort="5" velocity="2"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="fore"/><origin xyz="0 0 $(arg reach)"/>
    <axis xyz="1 0 0"/><limit lower="-2.0" upper="2.0" effort="5" velocity="2"/>
  </joint>
</robot>
"""


def write_package(root: Path) -> Path:
    """The package under ``root``; returns its xacro."""
    pkg = root / PACKAGE
    (pkg / "urdf").mkdir(parents=True, exist_ok=True)
    (pkg / "meshes").mkdir(exist_ok=True)
    (pkg / "package.xml").write_text(
        f'<?xml version="1.0"?><package format="3"><name>{PACKAGE}</name>'
        "<version>0.1.0</version><description>my arm</description>"
        '<maintainer email="me@example.com">me</maintainer><license>MIT</license></package>')
    # in millimetres, as CAD exports them: the xacro scales them by 0.001
    base = trimesh.creation.box(extents=(120.0, 120.0, 50.0))
    base.apply_translation((0, 0, 25.0))
    base.export(pkg / "meshes" / "base.stl")
    link = trimesh.creation.cylinder(radius=20.0, height=260.0, sections=32)
    link.apply_translation((0, 0, 150.0))
    link.export(pkg / "meshes" / "link.stl")
    xacro = pkg / "urdf" / "my_arm.urdf.xacro"
    xacro.write_text(XACRO)
    return xacro


root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp())
xacro = write_package(root)
print(f"wrote {xacro}")

# what `arduinobot check FILE --package-dir DIR --arg reach=0.32` prints
report = check_model(xacro, package_dirs=[root], args={"reach": "0.32"})
for finding in report.findings:
    print(" ", finding.line())
if report.failed:
    sys.exit(1)

desc = load_description(xacro, package_dirs=[root], args={"reach": "0.32"})
print(f"{desc.robot.name}: joints {list(desc.robot.actuated_joints)}, "
      f"tool point on {desc.tcp.parent_link} ({desc.tcp.source})")

# the service's request -> reply path, in this process: no SRDF, so the group is "all"
service = LocalService(desc)
reply = service.request("plan", {"goal": {"joints": {"yaw": 1.5, "elbow": 1.2}}, "seed": 1})
print(f"planned: {reply['duration']:.3f} s, {len(reply['trajectory']['points'])} samples, "
      f"certified {reply['verification']['certified']}")
