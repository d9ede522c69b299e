"""LeRobot's SO-101 as its published folder holds it (TheRobotStudio/SO-ARM100,
``Simulation/SO101``): ``so101_new_calib.urdf`` beside an ``assets/`` folder of STL
meshes named by relative paths, no SRDF, no MoveIt package, no ``package.xml``.

The joints, links, origins, limits and inertials are the published URDF's, as is its
massless ``gripper_frame_link`` on a fixed joint (with the stray ``<origin>`` inside the
``<link>`` the generator leaves). Each mesh is a box spanning the published mesh's
bounding box (metres, in the mesh's own frame, measured from the published STLs), so
sizes, reach and clearances are realistic while the fixture stays small and
deterministic. The fixed jaw (``wrist_roll_follower_so101_v1``) is two boxes, the
gripper's body and its finger (:data:`MESH_PARTS`): one box spanning both would fill the
space between the jaws where a cube is held.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

URDF_NAME = "so101_new_calib.urdf"

#: mesh -> (min corner, max corner) [m] of the published STL.
MESH_BOUNDS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "base_motor_holder_so101_v1": ((-0.0224, 0.0381, -0.0208), (0.0253, 0.0695, 0.0594)),
    "base_so101_v2": ((-0.0555, 0.0, -0.016), (0.0555, 0.072, 0.071)),
    "motor_holder_so101_base_v1": ((-0.0538, -0.0551, -0.0289), (-0.0258, -0.017, 0.0262)),
    "motor_holder_so101_wrist_v1": ((-0.0538, -0.0539, -0.0302), (-0.0258, -0.017, 0.0262)),
    "moving_jaw_so101_v1": ((-0.0123, -0.082, -0.024), (0.01, 0.01, 0.024)),
    "rotation_pitch_so101_v1": ((-0.0598, 0.0002, -0.023), (0.0, 0.0844, 0.023)),
    "sts3215_03a_no_horn_v1": ((-0.0227, -0.0124, -0.0194), (0.0227, 0.0124, 0.0202)),
    "sts3215_03a_v1": ((-0.0227, -0.0124, -0.0194), (0.0227, 0.0124, 0.0202)),
    "under_arm_so101_v1": ((-0.0538, -0.044, -0.0342), (0.0768, -0.02, 0.0302)),
    "upper_arm_so101_v1": ((-0.0651, 0.0, -0.0356), (0.0771, 0.0245, 0.0317)),
    "waveshare_mounting_plate_so101_v2": ((-0.0255, -0.021, 0.0), (0.0255, 0.021, 0.0076)),
    "wrist_roll_follower_so101_v1": ((-0.0352, -0.0242, -0.0001), (0.03, 0.0278, 0.1054)),
    "wrist_roll_pitch_so101_v2": ((-0.0271, -0.02, -0.0378), (0.0352, 0.0157, 0.04)),
}

#: meshes drawn as several boxes (min corner, max corner) [m], measured from the
#: published STL's sections: the fixed jaw's body (z < 0.045) and its finger, whose
#: inner face is at x <= -0.0079 (the finger's tip; -0.0116 to -0.0133 along it)
MESH_PARTS: dict[str, tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...]] = {
    "wrist_roll_follower_so101_v1": (((-0.0352, -0.0242, -0.0001), (0.03, 0.0278, 0.045)),
                                     ((-0.0352, -0.0122, 0.045), (-0.0079, 0.0122, 0.1054))),
}

# link -> (inertial xyz, mass, inertia ixx ixy ixz iyy iyz izz, [(mesh, xyz, rpy)])
_LINKS: list[tuple[str, str, float, str, list[tuple[str, str, str]]]] = [
    ("base_link", "0.0137179 -5.19711e-05 0.0334843", 0.147,
     'ixx="0.000114686" ixy="-4.59787e-07" ixz="4.97151e-06" iyy="0.000136117" '
     'iyz="9.75275e-08" izz="0.000130364"',
     [("base_motor_holder_so101_v1", "-0.00636471 -9.94414e-05 -0.0024", "1.5708 0 1.5708"),
      ("base_so101_v2", "-0.00636471 -8.97657e-09 -0.0024", "1.5708 0 1.5708"),
      ("sts3215_03a_v1", "0.0263353 -8.97657e-09 0.0437", "0 0 0"),
      ("waveshare_mounting_plate_so101_v2", "-0.0309827 -0.000199441 0.0474",
       "1.5708 0 1.5708")]),
    ("shoulder_link", "-0.0307604 -1.66727e-05 -0.0252713", 0.100006,
     'ixx="8.3759e-05" ixy="7.55525e-08" ixz="-1.16342e-06" iyy="8.10403e-05" '
     'iyz="1.54663e-07" izz="2.39783e-05"',
     [("sts3215_03a_v1", "-0.0303992 0.000422241 -0.0417", "1.5708 1.5708 0"),
      ("motor_holder_so101_base_v1", "-0.0675992 -0.000177759 0.0158499", "1.5708 -1.5708 0"),
      ("rotation_pitch_so101_v1", "0.0122008 2.22413e-05 0.0464", "-1.5708 0 0")]),
    ("upper_arm_link", "-0.0898471 -0.00838224 0.0184089", 0.103,
     'ixx="4.08002e-05" ixy="-1.97819e-05" ixz="-4.03016e-08" iyy="0.000147318" '
     'iyz="8.97326e-09" izz="0.000142487"',
     [("sts3215_03a_v1", "-0.11257 -0.0155 0.0187", "-3.14159 0 -1.5708"),
      ("upper_arm_so101_v1", "-0.065085 0.012 0.0182", "3.14159 0 0")]),
    ("lower_arm_link", "-0.0980701 0.00324376 0.0182831", 0.104,
     'ixx="2.87438e-05" ixy="7.41152e-06" ixz="1.26409e-06" iyy="0.000159844" '
     'iyz="-4.90188e-08" izz="0.00014529"',
     [("under_arm_so101_v1", "-0.0648499 -0.032 0.0182", "3.14159 0 0"),
      ("motor_holder_so101_wrist_v1", "-0.0648499 -0.032 0.018", "-3.14159 0 0"),
      ("sts3215_03a_v1", "-0.1224 0.0052 0.0187", "-3.14159 0 -3.14159")]),
    ("wrist_link", "-0.000103312 -0.0386143 0.0281156", 0.079,
     'ixx="3.68263e-05" ixy="1.7893e-08" ixz="-5.28128e-08" iyy="2.5391e-05" '
     'iyz="3.6412e-06" izz="2.1e-05"',
     [("sts3215_03a_no_horn_v1", "0 -0.0424 0.0306", "1.5708 1.5708 0"),
      ("wrist_roll_pitch_so101_v2", "0 -0.028 0.0181", "-1.5708 -1.5708 0")]),
    ("gripper_link", "0.000213627 0.000245138 -0.025187", 0.087,
     'ixx="2.75087e-05" ixy="-3.35241e-07" ixz="-5.7352e-06" iyy="4.33657e-05" '
     'iyz="-5.17847e-08" izz="3.45059e-05"',
     [("sts3215_03a_v1", "0.0077 0.0001 -0.0234", "-1.5708 0 0"),
      ("wrist_roll_follower_so101_v1", "0 -0.000218214 0.000949706", "-3.14159 0 0")]),
    ("moving_jaw_so101_v1_link", "-0.00157495 -0.0300244 0.0192755", 0.012,
     'ixx="6.61427e-06" ixy="-3.19807e-07" ixz="-5.90717e-09" iyy="1.89032e-06" '
     'iyz="-1.09945e-07" izz="5.28738e-06"',
     [("moving_jaw_so101_v1", "0 0 0.0189", "0 0 0")]),
]

# name, parent, child, origin xyz, origin rpy, lower, upper (all revolute about z)
_JOINTS = [
    ("shoulder_pan", "base_link", "shoulder_link", "0.0388353 -8.97657e-09 0.0624",
     "3.14159 0 -3.14159", -1.91986, 1.91986),
    ("shoulder_lift", "shoulder_link", "upper_arm_link", "-0.0303992 -0.0182778 -0.0542",
     "-1.5708 -1.5708 0", -1.74533, 1.74533),
    ("elbow_flex", "upper_arm_link", "lower_arm_link", "-0.11257 -0.028 0",
     "0 0 1.5708", -1.69, 1.69),
    ("wrist_flex", "lower_arm_link", "wrist_link", "-0.1349 0.0052 0", "0 0 -1.5708",
     -1.65806, 1.65806),
    ("wrist_roll", "wrist_link", "gripper_link", "0 -0.0611 0.0181", "1.5708 0.0486795 3.14159",
     -2.74385, 2.84121),
    ("gripper", "gripper_link", "moving_jaw_so101_v1_link", "0.0202 0.0188 -0.0234",
     "1.5708 0 0", -0.174533, 1.74533),
]

ARM_JOINTS = tuple(j[0] for j in _JOINTS[:5])
GRIPPER_JOINT = "gripper"


def _link_xml(name: str, com: str, mass: float, inertia: str,
              parts: list[tuple[str, str, str]]) -> str:
    out = [f'  <link name="{name}">\n    <inertial>\n      <origin xyz="{com}" rpy="0 0 0"/>'
           f'\n      <mass value="{mass}"/>\n      <inertia {inertia}/>\n    </inertial>\n']
    for mesh, xyz, rpy in parts:
        geo = (f'<origin xyz="{xyz}" rpy="{rpy}"/>\n      <geometry>\n        <mesh '
               f'filename="assets/{mesh}.stl"/>\n      </geometry>')
        out.append(f"    <!-- Part {mesh} -->\n    <visual>\n      {geo}\n      <material "
                   f'name="3d_printed"/>\n    </visual>\n    <collision>\n      {geo}\n'
                   "    </collision>\n")
    out.append("  </link>\n")
    return "".join(out)


def so101_urdf(name: str = "so101_new_calib") -> str:
    """The published ``so101_new_calib.urdf``'s structure, meshes under ``assets/``;
    ``name`` another robot name (one the shipped configs do not know)."""
    parts = ['<?xml version="1.0" encoding="utf-8"?>\n<!-- Generated using onshape-to-robot -->',
             '\n<robot name="' + name + '">\n  <material name="3d_printed">\n'
             '    <color rgba="1.0 0.82 0.12 1.0"/>\n  </material>\n']
    parts += [_link_xml(*link) for link in _LINKS[:6]]
    # the published dummy frame: a stray <origin> in the link, a 1e-9 kg zero inertia
    parts.append("""  <!-- Gripper frame (dummy link + fixed joint) -->
  <link name="gripper_frame_link">
    <origin xyz="0 0 0" rpy="0 -0 0"/>
    <inertial>
      <origin xyz="0 0 0" rpy="0 0 0"/>
      <mass value="1e-9"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>
    </inertial>
  </link>
  <joint name="gripper_frame_joint" type="fixed">
    <origin xyz="-0.0079 -0.000218121 -0.0981274" rpy="0 3.14159 0"/>
    <parent link="gripper_link"/>
    <child link="gripper_frame_link"/>
    <axis xyz="0 0 0"/>
  </joint>
""")
    parts.append(_link_xml(*_LINKS[6]))
    for name, parent, child, xyz, rpy, lo, hi in reversed(_JOINTS):  # published order
        parts.append(f"""  <joint name="{name}" type="revolute">
    <origin xyz="{xyz}" rpy="{rpy}"/>
    <parent link="{parent}"/>
    <child link="{child}"/>
    <axis xyz="0 0 1"/>
    <limit effort="10" velocity="10" lower="{lo}" upper="{hi}"/>
  </joint>
""")
    parts.append("</robot>\n")
    return "".join(parts)


def make_so101(root: Path, *, config: bool = False, name: str = "so101_new_calib") -> Path:
    """Write the published folder under ``root / "SO101"``; the URDF's path.

    ``config=True`` adds a ``config/`` folder beside the bare URDF (an SRDF with the
    groups ``arm`` and ``gripper``), as an owner who wrote one would keep it; ``name``:
    the robot's name (another than the published one: an arm no shipped config knows)."""
    folder = root / "SO101"
    (folder / "assets").mkdir(parents=True, exist_ok=True)
    for mesh, bounds in MESH_BOUNDS.items():
        boxes = []
        for lo, hi in MESH_PARTS.get(mesh, (bounds,)):
            box = trimesh.creation.box(extents=[h - low for low, h in zip(lo, hi)])
            box.apply_translation([(low + h) / 2 for low, h in zip(lo, hi)])
            boxes.append(box)
        trimesh.util.concatenate(boxes).export(folder / "assets" / f"{mesh}.stl")
    urdf = folder / URDF_NAME
    urdf.write_text(so101_urdf(name))
    if config:
        (folder / "config").mkdir(exist_ok=True)
        (folder / "config" / f"{name}.srdf").write_text(
            OWNER_SRDF.replace("so101_new_calib", name))
    return urdf


OWNER_SRDF = """<?xml version="1.0"?>
<robot name="so101_new_calib">
  <group name="arm"><chain base_link="base_link" tip_link="gripper_frame_link"/></group>
  <group name="gripper"><joint name="gripper"/></group>
  <group_state name="rest" group="arm">
    <joint name="shoulder_pan" value="0"/><joint name="shoulder_lift" value="-1.6"/>
    <joint name="elbow_flex" value="1.55"/><joint name="wrist_flex" value="0.7"/>
    <joint name="wrist_roll" value="0"/>
  </group_state>
  <end_effector name="jaws" parent_link="gripper_frame_link" group="gripper"
                parent_group="arm"/>
</robot>
"""


#: a LeRobot calibration file of an SO-101 follower (``lerobot-calibrate``'s JSON, as
#: ``~/.cache/huggingface/lerobot/calibration/robots/so101_follower/ID.json`` holds
#: it): servo ids 1-6, each arm joint's range spanning its URDF limits about the middle
#: (4095 ticks a turn), the gripper's range its 0-100 scale
CALIBRATION: dict[str, dict[str, int]] = {
    "shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": -1470, "range_min": 790,
                     "range_max": 3306},
    "shoulder_lift": {"id": 2, "drive_mode": 0, "homing_offset": 1012, "range_min": 900,
                      "range_max": 3196},
    "elbow_flex": {"id": 3, "drive_mode": 0, "homing_offset": -893, "range_min": 930,
                   "range_max": 3166},
    "wrist_flex": {"id": 4, "drive_mode": 0, "homing_offset": 1290, "range_min": 950,
                   "range_max": 3146},
    "wrist_roll": {"id": 5, "drive_mode": 0, "homing_offset": -517, "range_min": 180,
                   "range_max": 3916},
    "gripper": {"id": 6, "drive_mode": 0, "homing_offset": 1414, "range_min": 2030,
                "range_max": 3460},
}
GRIPPER_LIMITS = (-0.174533, 1.74533)  # [rad] the URDF's gripper joint


def calibration_ticks(joint: str, q: float) -> float:
    """LeRobot's unnormalisation of ``q`` [rad] for :data:`CALIBRATION`, spelled out:
    degrees about the range's middle for an arm joint, the 0-100 scale laid onto the
    URDF's limits for the gripper."""
    c = CALIBRATION[joint]
    lo, hi = c["range_min"], c["range_max"]
    if joint == GRIPPER_JOINT:
        pct = 100 * (q - GRIPPER_LIMITS[0]) / (GRIPPER_LIMITS[1] - GRIPPER_LIMITS[0])
        return pct / 100 * (hi - lo) + lo
    return np.degrees(q) * 4095 / 360 + (lo + hi) / 2
