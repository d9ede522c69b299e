"""A 6-joint test arm (box and cylinder links, a spherical wrist), written as a package:
a robot whose IK can choose the tool's orientation, for pose goals and held-orientation
lines. Kinematics like a small industrial arm: yaw, shoulder pitch, elbow pitch, then a
roll-pitch-roll wrist; reach about 0.6 m; the tcp 0.1 m beyond the last joint."""

from __future__ import annotations

from pathlib import Path

PACKAGE = "six_bot_description"


def _link(name: str, geometry: str, xyz: str, mass: float = 0.5) -> str:
    return f"""  <link name="{name}">
    <visual><origin xyz="{xyz}"/><geometry>{geometry}</geometry></visual>
    <collision><origin xyz="{xyz}"/><geometry>{geometry}</geometry></collision>
    <inertial><origin xyz="{xyz}"/><mass value="{mass}"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.002"/></inertial>
  </link>
"""


def _joint(name: str, parent: str, child: str, xyz: str, axis: str, limit: float = 2.8
           ) -> str:
    return f"""  <joint name="{name}" type="revolute">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{xyz}"/><axis xyz="{axis}"/>
    <limit lower="-{limit}" upper="{limit}" velocity="3.0" effort="200"/>
  </joint>
"""


def six_joint_urdf() -> str:
    links = [
        _link("base", '<box size="0.2 0.2 0.05"/>', "0 0 0.025", 2.0),
        _link("turret", '<cylinder radius="0.04" length="0.1"/>', "0 0 0.05"),
        _link("upper_arm", '<box size="0.05 0.05 0.3"/>', "0 0 0.15"),
        _link("forearm", '<box size="0.04 0.04 0.25"/>', "0 0 0.125"),
        _link("wrist_1", '<cylinder radius="0.025" length="0.04"/>', "0 0 0.02", 0.2),
        _link("wrist_2", '<cylinder radius="0.025" length="0.04"/>', "0 0 0.02", 0.2),
        _link("flange", '<box size="0.03 0.03 0.02"/>', "0 0 0.01", 0.1),
    ]
    joints = [
        _joint("j1", "base", "turret", "0 0 0.05", "0 0 1"),
        _joint("j2", "turret", "upper_arm", "0 0 0.1", "0 1 0"),
        _joint("j3", "upper_arm", "forearm", "0 0 0.3", "0 1 0"),
        _joint("j4", "forearm", "wrist_1", "0 0 0.25", "0 0 1"),
        _joint("j5", "wrist_1", "wrist_2", "0 0 0.04", "0 1 0"),
        _joint("j6", "wrist_2", "flange", "0 0 0.04", "0 0 1"),
    ]
    return ('<?xml version="1.0"?>\n<robot name="six_bot">\n' + "".join(links)
            + "".join(joints) + "</robot>\n")


SRDF = """<?xml version="1.0"?>
<robot name="six_bot">
  <group name="arm"><chain base_link="base" tip_link="flange"/></group>
  <group_state name="home" group="arm">
    <joint name="j1" value="0"/><joint name="j2" value="0.5"/><joint name="j3" value="1.0"/>
    <joint name="j4" value="0"/><joint name="j5" value="0.8"/><joint name="j6" value="0"/>
  </group_state>
  <disable_collisions link1="base" link2="turret" reason="Adjacent"/>
  <disable_collisions link1="turret" link2="upper_arm" reason="Adjacent"/>
  <disable_collisions link1="upper_arm" link2="forearm" reason="Adjacent"/>
  <disable_collisions link1="forearm" link2="wrist_1" reason="Adjacent"/>
  <disable_collisions link1="wrist_1" link2="wrist_2" reason="Adjacent"/>
  <disable_collisions link1="wrist_2" link2="flange" reason="Adjacent"/>
  <disable_collisions link1="forearm" link2="wrist_2" reason="Never"/>
  <disable_collisions link1="forearm" link2="flange" reason="Never"/>
  <disable_collisions link1="wrist_1" link2="flange" reason="Never"/>
</robot>
"""

TCP_YAML = """tcp:
  parent_link: flange
  xyz: [0.0, 0.0, 0.1]
"""

JOINT_LIMITS_YAML = "joint_limits:\n" + "".join(f"""  j{i}:
    has_velocity_limits: true
    max_velocity: 3.0
    has_acceleration_limits: true
    max_acceleration: 10.0
""" for i in range(1, 7))


def make_six_joint(root: Path) -> Path:
    """Write the package under ``root``; the URDF's path."""
    pkg = root / PACKAGE
    (pkg / "urdf").mkdir(parents=True, exist_ok=True)
    (pkg / "config").mkdir(exist_ok=True)
    (pkg / "package.xml").write_text(
        f'<?xml version="1.0"?><package format="3"><name>{PACKAGE}</name>'
        "<version>1.0.0</version><description>test</description>"
        '<maintainer email="a@b.c">me</maintainer><license>MIT</license></package>')
    (pkg / "config" / "six_bot.srdf").write_text(SRDF)
    (pkg / "config" / "tcp.yaml").write_text(TCP_YAML)
    (pkg / "config" / "joint_limits.yaml").write_text(JOINT_LIMITS_YAML)
    urdf = pkg / "urdf" / "six_bot.urdf"
    urdf.write_text(six_joint_urdf())
    return urdf
