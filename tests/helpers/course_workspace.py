"""A user's colcon workspace as the ROS 2 arduinobot course and the MoveIt Setup Assistant
leave it: the test fixture (and bench input) for "bring your own robot".

``src/`` holds three packages:

- ``arduinobot_description``: a multi-file xacro (properties and macros, links and joints,
  an RGB camera on a fixed joint, gazebo and ros2_control tags with ``$(find
  arduinobot_controller)``, ``is_sim`` argument), CAD-like meshes in millimetres
  (``scale="0.001 0.001 0.001"``, 6k to 54k triangles, several with open edges), a
  ``<material>`` inside a ``<geometry>``, and no ``config/`` folder.
- ``arduinobot_controller``: the ros2_control controllers yaml.
- ``arduinobot_moveit``: what the MoveIt Setup Assistant writes: ``.setup_assistant``,
  an SRDF computed before the camera was added (groups with virtual and fixed joints, a
  ``home`` state for both groups), joint_limits.yaml scaling speeds to 0.1 by default,
  kinematics, initial positions, controllers.

The arm is the shipped one (robot-model.md): same links, joints, origins, axes and
limits; each mesh is the shipped centimetre part scaled to millimetres and refined by
edge bisection (so the surface, and where it sits, are unchanged), written as binary STL.
Everything is deterministic: two calls write byte-identical files.

Run ``python -m tests.helpers.course_workspace OUT_DIR`` to write one and print its paths.
"""

from __future__ import annotations

import struct
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

REPO = Path(__file__).resolve().parents[2]
SHIPPED_MESHES = REPO / "src" / "arduinobot" / "description" / "arduinobot_description" / "meshes"

DESCRIPTION = "arduinobot_description"
CONTROLLER = "arduinobot_controller"
MOVEIT = "arduinobot_moveit"


@dataclass(frozen=True)
class CourseWorkspace:
    """Paths of a generated workspace.

    Attributes:
        src: the colcon ``src`` folder (pass it as a package dir).
        description_pkg, controller_pkg, moveit_pkg: the three package folders.
        xacro: the top-level ``urdf/arduinobot.urdf.xacro``.
    """

    src: Path
    description_pkg: Path
    controller_pkg: Path
    moveit_pkg: Path
    xacro: Path


@dataclass(frozen=True)
class _Part:
    mesh: str          # file name in meshes/
    factor: float      # target triangles as a multiple of tri_target (0: keep as shipped)
    open_faces: int    # faces deleted to leave open edges (0: stays watertight)


# Big parts get fine tessellations (20k..54k at the default target), the fingers stay as
# CAD exports them (~6k), four parts have holes.
PARTS: dict[str, _Part] = {
    "base_link": _Part("basement.STL", 1.6, 5),
    "base_plate": _Part("base_plate.STL", 2.7, 0),
    "forward_drive_arm": _Part("forward_drive_arm.STL", 2.0, 4),
    "horizontal_arm": _Part("horizontal_arm.STL", 1.25, 0),
    "claw_support": _Part("claw_support.STL", 1.0, 3),
    "gripper_right": _Part("right_finger.STL", 0.0, 2),
    "gripper_left": _Part("left_finger.STL", 0.0, 0),
}
CAMERA_MESH = "rgb_camera.STL"
CAMERA_TRIANGLES = 2000


# --- meshes -------------------------------------------------------------------------------

def refine(vertices: np.ndarray, faces: np.ndarray, target: int
           ) -> tuple[np.ndarray, np.ndarray]:
    """Split the longest edges at their midpoints until the closed mesh has ``target``
    triangles (or one less). Each face is split conformingly into 2, 3 or 4, so the
    surface is unchanged, a watertight mesh stays watertight and winding is kept."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    while len(f) < target - 1:
        pairs = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        edges, inverse = np.unique(pairs, axis=0, return_inverse=True)
        face_edges = inverse.reshape(-1, 3)  # e0 = (a, b), e1 = (b, c), e2 = (c, a)
        k = min((target - len(f)) // 2, len(edges))  # each split adds 2 faces when closed
        length = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1)
        chosen = np.argsort(-length, kind="stable")[:k]
        mid = np.full(len(edges), -1, dtype=np.int64)
        mid[chosen] = len(v) + np.arange(k)
        v = np.vstack([v, 0.5 * (v[edges[chosen, 0]] + v[edges[chosen, 1]])])
        m = mid[face_edges]
        s = m >= 0
        count = s.sum(axis=1)
        # rotate each face so one split edge is e0, or two split edges are e0 and e1
        r = np.zeros(len(f), dtype=np.int64)
        r[count == 1] = np.argmax(s[count == 1], axis=1)
        r[count == 2] = (np.argmin(s[count == 2], axis=1) + 1) % 3
        idx = (r[:, None] + np.arange(3)) % 3
        fr = np.take_along_axis(f, idx, axis=1)
        mr = np.take_along_axis(m, idx, axis=1)
        a, b, c = fr.T
        m0, m1, m2 = mr.T
        out = []
        for n, tris in (
            (0, [(a, b, c)]),
            (1, [(a, m0, c), (m0, b, c)]),
            (2, [(m0, b, m1), (a, m0, m1), (a, m1, c)]),
            (3, [(a, m0, m2), (m0, b, m1), (m2, m1, c), (m0, m1, m2)]),
        ):
            sel = count == n
            out.extend(np.stack([x[sel] for x in tri], axis=1) for tri in tris)
        f = np.vstack(out)
    return v, f


def punch_holes(vertices: np.ndarray, faces: np.ndarray, n: int, rng: np.random.Generator
                ) -> np.ndarray:
    """Delete ``n`` faces that share no vertex with each other and touch none of the
    mesh's extreme planes: open edges, the same bounding box and the same vertices."""
    if n == 0:
        return faces
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    margin = 0.05 * (hi - lo)
    tri = vertices[faces]
    inner = np.all((tri > lo + margin) & (tri < hi - margin), axis=(1, 2))
    candidates = np.flatnonzero(inner)
    used: set[int] = set()
    drop: list[int] = []
    for i in rng.permutation(candidates):
        if used.isdisjoint(faces[i].tolist()):
            drop.append(int(i))
            used.update(faces[i].tolist())
            if len(drop) == n:
                break
    return np.delete(faces, drop, axis=0)


def write_binary_stl(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """A binary STL (float32, unit normals, fixed header): byte-identical for equal input."""
    tri = vertices[faces].astype(np.float32)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype(np.float64)
    norm = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, norm, out=np.zeros_like(normals), where=norm > 0)
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = normals
    rec["v"] = tri
    header = b"binary STL exported by SolidWorks-like CAD, units: mm".ljust(80, b" ")
    path.write_bytes(header + struct.pack("<I", len(faces)) + rec.tobytes())


def _shipped(name: str) -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.load(str(SHIPPED_MESHES / name), force="mesh", process=True)
    return np.asarray(m.vertices, dtype=np.float64) * 10.0, np.asarray(m.faces, dtype=np.int64)


def camera_mesh() -> tuple[np.ndarray, np.ndarray]:
    """A small RGB camera in mm, in the CAD's corner frame: a 40 x 30 x 25 body from the
    origin, a 16 mm lens on its +y face."""
    body = trimesh.creation.box(extents=(40.0, 30.0, 25.0))
    body.apply_translation((20.0, 15.0, 12.5))
    lens = trimesh.creation.cylinder(radius=8.0, height=8.0, sections=32)
    lens.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0)))
    lens.apply_translation((20.0, 34.0, 12.5))
    both = trimesh.util.concatenate([body, lens])
    return refine(both.vertices, both.faces, CAMERA_TRIANGLES)


def write_meshes(folder: Path, *, tri_target: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    for part in PARTS.values():
        v, f = _shipped(part.mesh)
        if part.factor > 0:
            v, f = refine(v, f, max(len(f), round(part.factor * tri_target)))
        f = punch_holes(v, f, part.open_faces, rng)
        write_binary_stl(folder / part.mesh, v, f)
    write_binary_stl(folder / CAMERA_MESH, *camera_mesh())


# --- arduinobot_description ---------------------------------------------------------------

def _manifest(name: str, description: str, build: str, depends: list[tuple[str, str]]) -> str:
    deps = "\n".join(f"  <{kind}>{pkg}</{kind}>" for kind, pkg in depends)
    return f"""<?xml version="1.0"?>
<?xml-model href="http://download.ros.org/schema/package_format3.xsd" schematypens="http://www.w3.org/2001/XMLSchema"?>
<package format="3">
  <name>{name}</name>
  <version>0.0.0</version>
  <description>{description}</description>
  <maintainer email="student@todo.todo">student</maintainer>
  <license>Apache-2.0</license>

  <buildtool_depend>{build}</buildtool_depend>

{deps}

  <test_depend>ament_lint_auto</test_depend>
  <test_depend>ament_lint_common</test_depend>

  <export>
    <build_type>{build}</build_type>
  </export>
</package>
"""


def _cmake(name: str, dirs: str) -> str:
    return f"""cmake_minimum_required(VERSION 3.8)
project({name})

if(CMAKE_COMPILER_IS_GNUCXX OR CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  add_compile_options(-Wall -Wextra -Wpedantic)
endif()

# find dependencies
find_package(ament_cmake REQUIRED)

install(
  DIRECTORY {dirs}
  DESTINATION share/${{PROJECT_NAME}}
)

if(BUILD_TESTING)
  find_package(ament_lint_auto REQUIRED)
  set(ament_cmake_copyright_FOUND TRUE)
  set(ament_cmake_cpplint_FOUND TRUE)
  ament_lint_auto_find_test_dependencies()
endif()

ament_package()
"""


TOP_XACRO = """<?xml version="1.0"?>

<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="arduinobot">

  <!-- Start GZ or Ignition depending on ROS 2 Version -->
  <xacro:arg name="is_sim" default="true"/>

  <!-- Useful XACRO Variables (Properties) and macros -->
  <xacro:include filename="$(find arduinobot_description)/urdf/common_properties.xacro" />

  <!-- Links and joints of the arm -->
  <xacro:include filename="$(find arduinobot_description)/urdf/robot_structure.xacro" />

  <!-- The RGB camera on the base -->
  <xacro:include filename="$(find arduinobot_description)/urdf/camera.xacro" />

  <!-- Include Gazebo Parameters -->
  <xacro:include filename="$(find arduinobot_description)/urdf/arduinobot_gazebo.xacro" />

  <!-- Include ros2_control Plugins -->
  <xacro:include filename="$(find arduinobot_description)/urdf/arduinobot_control.xacro" />

</robot>
"""

COMMON_XACRO = """<?xml version="1.0"?>

<robot xmlns:xacro="http://www.ros.org/wiki/xacro">

  <xacro:property name="PI" value="3.14159"/>
  <xacro:property name="effort" value="30.0"/>
  <xacro:property name="velocity" value="10.0"/>

  <!-- Useful Macros -->
  <xacro:macro name="default_inertial" params="mass">
    <inertial>
      <mass value="${mass}" />
      <inertia ixx="0.001" ixy="0.0" ixz="0.0"
               iyy="0.001" iyz="0.0"
               izz="0.001" />
    </inertial>
  </xacro:macro>

</robot>
"""

# link, mass, visual/collision origin xyz and rpy, as robot-model.md (the course's figures)
_LINKS = [
    ("base_link", "1.0", "-0.5 -0.5 0", "0 0 0"),
    ("base_plate", "0.1", "-0.39 -0.39 -0.56", "0 0 0"),
    ("forward_drive_arm", "0.1", "0.19 0.06 -0.08", "0 -${PI/2} ${PI/2}"),
    ("horizontal_arm", "0.1", "-0.03 -0.4 -0.06", "${PI/2} 0 ${PI/2}"),
    ("claw_support", "0.05", "0 -0.05 -0.15", "0 0 ${PI/2}"),
    ("gripper_right", "0.01", "-0.1 0.50 -0.1", "0 0 -${PI/2}"),
    ("gripper_left", "0.01", "-0.04 0.50 -0.1", "0 0 -${PI/2}"),
]


def _link(name: str, mass: str, xyz: str, rpy: str, mesh: str, *, comment: str = "",
          visual_extra: str = "") -> str:
    geom = (f'<mesh filename="package://{DESCRIPTION}/meshes/{mesh}" '
            'scale="0.001 0.001 0.001"/>')
    return f"""{comment}  <link name="{name}">
    <xacro:default_inertial mass="{mass}"/>
    <visual>
      <origin rpy="{rpy}" xyz="{xyz}"/>
      <geometry>
        {geom}{visual_extra}
      </geometry>
    </visual>
    <collision>
      <origin rpy="{rpy}" xyz="{xyz}"/>
      <geometry>
        {geom}
      </geometry>
    </collision>
  </link>
"""


def _revolute(name: str, parent: str, child: str, xyz: str, axis: str, lower: str,
              upper: str, extra: str = "") -> str:
    return f"""
  <joint name="{name}" type="revolute">
    <parent link="{parent}"/>
    <child link="{child}"/>
    <axis xyz="{axis}"/>
    <origin rpy="0 0 0" xyz="{xyz}"/>
    <limit lower="{lower}" upper="{upper}"
           effort="${{effort}}" velocity="${{velocity}}"/>{extra}
  </joint>

"""


def _fixed(name: str, parent: str, child: str, xyz: str) -> str:
    return f"""
  <joint name="{name}" type="fixed">
    <parent link="{parent}"/>
    <child link="{child}"/>
    <origin rpy="0 0 0" xyz="{xyz}"/>
  </joint>

"""


def structure_xacro() -> str:
    links = {name: _link(name, mass, xyz, rpy, PARTS[name].mesh)
             for name, mass, xyz, rpy in _LINKS}
    body = ('  <link name="world"/>\n\n' + links["base_link"]
            + _fixed("virtual_joint", "world", "base_link", "0 0 0")
            + links["base_plate"]
            + _revolute("joint_1", "base_link", "base_plate", "0 0 0.307", "0 0 1",
                        "-${PI/2}", "${PI/2}")
            + links["forward_drive_arm"]
            + _revolute("joint_2", "base_plate", "forward_drive_arm", "-0.02 0 0.35",
                        "1 0 0", "-${PI/2}", "${PI/2}")
            + links["horizontal_arm"]
            + _revolute("joint_3", "forward_drive_arm", "horizontal_arm", "0 0 0.8",
                        "1 0 0", "-${PI/2}", "${PI/2}")
            + links["claw_support"]
            + _fixed("horizontal_arm_to_claw_support", "horizontal_arm", "claw_support",
                     "0 0.82 0")
            + links["gripper_right"]
            + _revolute("joint_4", "claw_support", "gripper_right", "-0.04 0.13 -0.1",
                        "0 0 1", "-${PI/2}", "0.0")
            + links["gripper_left"]
            + _revolute("joint_5", "claw_support", "gripper_left", "-0.22 0.13 -0.1",
                        "0 0 1", "0.0", "${PI/2}",
                        '\n    <mimic joint="joint_4" multiplier="-1"/>'))
    return ('<?xml version="1.0"?>\n\n<robot xmlns:xacro="http://www.ros.org/wiki/xacro">\n\n'
            + body + "</robot>\n")


# The camera sits in front of the basement's front face, at its bottom: below and outside
# the turntable, 2 cm above the floor. Mesh frame: the CAD's corner; the visual origin
# centres the body (40 x 30 x 25 mm) on the link frame.
CAMERA_JOINT_XYZ = (0.0, 0.40, 0.035)
CAMERA_VISUAL_XYZ = (-0.02, -0.015, -0.0125)


def camera_xacro() -> str:
    xyz = " ".join(f"{x:g}" for x in CAMERA_VISUAL_XYZ)
    material = """
        <!-- TODO: move the material out of the geometry (RViz complained?) -->
        <material name="camera_black">
          <color rgba="0.1 0.1 0.1 1.0"/>
        </material>"""
    link = _link("rgb_camera_link", "0.01", xyz, "0 0 0", CAMERA_MESH,
                 comment="  <!-- RGB camera bolted to the front of the base -->\n",
                 visual_extra=material)
    joint = _fixed("rgb_camera_joint", "base_link", "rgb_camera_link",
                   " ".join(f"{x:g}" for x in CAMERA_JOINT_XYZ))
    return ('<?xml version="1.0"?>\n\n<robot xmlns:xacro="http://www.ros.org/wiki/xacro">\n\n'
            + link + joint + "</robot>\n")


GAZEBO_XACRO = """<?xml version="1.0"?>

<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="arduinobot">

  <!-- ROS 2 Control -->
  <gazebo>
    <plugin filename="gz_ros2_control-system" name="gz_ros2_control::GazeboSimROS2ControlPlugin">
      <parameters>$(find arduinobot_controller)/config/arduinobot_controllers.yaml</parameters>
    </plugin>
  </gazebo>

  <gazebo reference="base_link">
    <material>Gazebo/Orange</material>
  </gazebo>

  <gazebo reference="gripper_right">
    <mu1>0.8</mu1>
    <mu2>0.8</mu2>
  </gazebo>

  <gazebo reference="gripper_left">
    <mu1>0.8</mu1>
    <mu2>0.8</mu2>
  </gazebo>

  <!-- Camera -->
  <gazebo reference="rgb_camera_link">
    <sensor name="rgb_camera" type="camera">
      <always_on>true</always_on>
      <visualize>true</visualize>
      <update_rate>30</update_rate>
      <topic>image_raw</topic>
      <gz_frame_id>rgb_camera_link</gz_frame_id>
      <camera name="rgb_camera">
        <horizontal_fov>1.089</horizontal_fov>
        <image>
          <format>R8G8B8</format>
          <width>640</width>
          <height>480</height>
        </image>
        <clip>
          <near>0.05</near>
          <far>8.0</far>
        </clip>
      </camera>
    </sensor>
  </gazebo>

</robot>
"""


def _control_joint(name: str, lower: str, upper: str, extra: str = "") -> str:
    return f"""
    <joint name="{name}">{extra}
      <command_interface name="position">
        <param name="min">{lower}</param>
        <param name="max">{upper}</param>
      </command_interface>
      <state_interface name="position"/>
    </joint>
"""


def control_xacro() -> str:
    joints = (_control_joint("joint_1", "-${PI / 2}", "${PI / 2}")
              + _control_joint("joint_2", "-${PI / 2}", "${PI / 2}")
              + _control_joint("joint_3", "-${PI / 2}", "${PI / 2}")
              + _control_joint("joint_4", "-${PI / 2}", "0.0")
              + _control_joint("joint_5", "0.0", "${PI / 2}", """
      <param name="mimic">joint_4</param>
      <param name="multiplier">-1</param>"""))
    return f"""<?xml version="1.0"?>

<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="arduinobot">

  <ros2_control name="RobotSystem" type="system">

    <!-- ros2_control Gazebo -->
    <xacro:if value="$(arg is_sim)">
      <hardware>
        <plugin>gz_ros2_control/GazeboSimSystem</plugin>
      </hardware>
    </xacro:if>

    <!-- ros2_control Real Robot -->
    <xacro:unless value="$(arg is_sim)">
      <hardware>
        <plugin>arduinobot_controller/ArduinobotInterface</plugin>
        <param name="port">/dev/ttyACM0</param>
      </hardware>
    </xacro:unless>
{joints}
  </ros2_control>

</robot>
"""


# --- arduinobot_controller ----------------------------------------------------------------

CONTROLLERS_YAML = """controller_manager:
  ros__parameters:
    update_rate: 10  # Hz

    arm_controller:
      type: joint_trajectory_controller/JointTrajectoryController

    gripper_controller:
      type: joint_trajectory_controller/JointTrajectoryController

    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster


arm_controller:
  ros__parameters:
    joints:
      - joint_1
      - joint_2
      - joint_3

    command_interfaces:
      - position

    state_interfaces:
      - position

    open_loop_control: true
    allow_integration_in_goal_trajectories: true

    gains:
      joint_1: {p: 1.0, i: 0.0, d: 0.1, i_clamp: 0.0}
      joint_2: {p: 1.0, i: 0.0, d: 0.1, i_clamp: 0.0}
      joint_3: {p: 1.0, i: 0.0, d: 0.1, i_clamp: 0.0}


gripper_controller:
  ros__parameters:
    joints:
      - joint_4

    command_interfaces:
      - position

    state_interfaces:
      - position

    open_loop_control: true
    allow_integration_in_goal_trajectories: true
"""


# --- arduinobot_moveit --------------------------------------------------------------------

SETUP_ASSISTANT = """moveit_setup_assistant_config:
  urdf:
    package: arduinobot_description
    relative_path: urdf/arduinobot.urdf.xacro
    xacro_args: ""
  srdf:
    relative_path: config/arduinobot.srdf
  package_settings:
    author_name: student
    author_email: student@todo.todo
    generated_timestamp: 1712345678
  control_xacro:
    command:
      - position
    state:
      - position
  modified_urdf:
    xacros:
      - control_xacro
"""

# Computed by the setup assistant before the camera existed: Adjacent pairs, and the
# Never pairs the project proves for these very parts (description's shipped SRDF).
_DISABLED = [
    ("base_link", "base_plate", "Adjacent"),
    ("base_link", "forward_drive_arm", "Never"),
    ("base_plate", "forward_drive_arm", "Adjacent"),
    ("claw_support", "gripper_left", "Adjacent"),
    ("claw_support", "gripper_right", "Adjacent"),
    ("claw_support", "horizontal_arm", "Adjacent"),
    ("forward_drive_arm", "horizontal_arm", "Adjacent"),
    ("gripper_left", "horizontal_arm", "Never"),
    ("gripper_right", "horizontal_arm", "Never"),
]


def srdf() -> str:
    pairs = "\n".join(f'    <disable_collisions link1="{a}" link2="{b}" reason="{r}"/>'
                      for a, b, r in _DISABLED)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!--This does not replace URDF, and is not an extension of URDF.
    This is a format for representing semantic information about the robot structure.
    A URDF file must exist for this robot as well, where the joints and the links that are referenced are defined
-->
<robot name="arduinobot">
    <!--GROUPS: Representation of a set of joints and links. This can be useful for specifying DOF to plan for, defining arms, end effectors, etc-->
    <!--LINKS: When a link is specified, the parent joint of that link (if it exists) is automatically included-->
    <!--JOINTS: When a joint is specified, the child link of that joint (which will always exist) is automatically included-->
    <!--CHAINS: When a chain is specified, all the links along the chain (including endpoints) are included in the group. Additionally, all the joints that are parents to included links are also included. This means that joints along the chain and the parent joint of the base link are included in the group-->
    <!--SUBGROUPS: Groups can also be formed by referencing to already defined group names-->
    <group name="arm">
        <joint name="virtual_joint"/>
        <joint name="joint_1"/>
        <joint name="joint_2"/>
        <joint name="joint_3"/>
        <joint name="horizontal_arm_to_claw_support"/>
    </group>
    <group name="gripper">
        <joint name="joint_4"/>
        <joint name="joint_5"/>
    </group>
    <!--GROUP STATES: Purpose: Define a named state for a particular group, in terms of joint values. This is useful to define states like 'folded arms'-->
    <group_state name="home" group="arm">
        <joint name="joint_1" value="0"/>
        <joint name="joint_2" value="0"/>
        <joint name="joint_3" value="0"/>
    </group_state>
    <group_state name="home" group="gripper">
        <joint name="joint_4" value="0"/>
        <joint name="joint_5" value="0"/>
    </group_state>
    <group_state name="open" group="gripper">
        <joint name="joint_4" value="-0.7"/>
        <joint name="joint_5" value="0.7"/>
    </group_state>
    <group_state name="closed" group="gripper">
        <joint name="joint_4" value="0"/>
        <joint name="joint_5" value="0"/>
    </group_state>
    <!--VIRTUAL JOINT: Purpose: this element defines a virtual joint between a robot link and an external frame of reference (considered fixed with respect to the robot)-->
    <virtual_joint name="virtual_joint" type="fixed" parent_frame="world" child_link="base_link"/>
    <!--DISABLE COLLISIONS: By default it is assumed that any link of the robot could potentially come into collision with any other link in the robot. This tag disables collision checking between a specified pair of links. -->
{pairs}
</robot>
"""


def joint_limits_yaml() -> str:
    entries = "".join(f"""  joint_{i}:
    has_velocity_limits: true
    max_velocity: 10.0
    has_acceleration_limits: false
    max_acceleration: 0
""" for i in range(1, 6))
    return f"""# joint_limits.yaml allows the dynamics properties specified in the URDF to be overwritten or augmented as needed

# For beginners, we downscale velocity and acceleration limits.
# You can always specify higher scaling factors (<= 1.0) in your motion requests.  # Increase the values below to 1.0 to always move at maximum speed.
default_velocity_scaling_factor: 0.1
default_acceleration_scaling_factor: 0.1

# Specific joint properties can be changed with the keys [max_position, min_position, max_velocity, max_acceleration]
# Joint limits can be turned off with [has_velocity_limits, has_acceleration_limits]
joint_limits:
{entries}"""


KINEMATICS_YAML = """arm:
  kinematics_solver: kdl_kinematics_plugin/KDLKinematicsPlugin
  kinematics_solver_search_resolution: 0.0050000000000000001
  kinematics_solver_timeout: 0.0050000000000000001
  position_only_ik: true
"""

INITIAL_POSITIONS_YAML = """# Default initial positions for arduinobot's ros2_control fake system

initial_positions:
  joint_1: 0
  joint_2: 0
  joint_3: 0
  joint_4: 0
  joint_5: 0
"""

MOVEIT_CONTROLLERS_YAML = """# MoveIt uses this configuration for controller management

moveit_controller_manager: moveit_simple_controller_manager/MoveItSimpleControllerManager

moveit_simple_controller_manager:
  controller_names:
    - arm_controller
    - gripper_controller

  arm_controller:
    type: FollowJointTrajectory
    joints:
      - joint_1
      - joint_2
      - joint_3
    action_ns: follow_joint_trajectory
    default: true
  gripper_controller:
    type: FollowJointTrajectory
    joints:
      - joint_4
    action_ns: follow_joint_trajectory
    default: true
"""

PILZ_YAML = """# Limits for the Pilz planner
cartesian_limits:
  max_trans_vel: 1.0
  max_trans_acc: 2.25
  max_trans_dec: -5.0
  max_rot_vel: 1.57
"""


# --- the workspace ------------------------------------------------------------------------

def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8", newline="\n")


def make_course_workspace(root: Path, *, tri_target: int = 20_000, seed: int = 0
                          ) -> CourseWorkspace:
    """Write the workspace under ``root`` (``root/src/...``; files there are overwritten).

    Args:
        root: the workspace folder (created if missing).
        tri_target: triangles of the smallest refined part; the others get 1.25x to
            2.7x that (20k..54k by default), the fingers keep their ~6k.
        seed: chooses the faces deleted to leave open edges.
    """
    src = Path(root) / "src"
    desc, ctrl, moveit = src / DESCRIPTION, src / CONTROLLER, src / MOVEIT

    _write(desc / "package.xml", _manifest(
        DESCRIPTION, "The URDF model of the arduinobot", "ament_cmake",
        [("exec_depend", d) for d in ("robot_state_publisher", "joint_state_publisher_gui",
                                      "rviz2", "ros2launch", "xacro", "ros_gz_sim",
                                      "ros_gz_bridge", "gz_ros2_control", CONTROLLER)]))
    _write(desc / "CMakeLists.txt", _cmake(DESCRIPTION, "meshes urdf"))
    urdf = desc / "urdf"
    _write(urdf / "arduinobot.urdf.xacro", TOP_XACRO)
    _write(urdf / "common_properties.xacro", COMMON_XACRO)
    _write(urdf / "robot_structure.xacro", structure_xacro())
    _write(urdf / "camera.xacro", camera_xacro())
    _write(urdf / "arduinobot_gazebo.xacro", GAZEBO_XACRO)
    _write(urdf / "arduinobot_control.xacro", control_xacro())
    write_meshes(desc / "meshes", tri_target=tri_target, seed=seed)

    _write(ctrl / "package.xml", _manifest(
        CONTROLLER, "Controllers and hardware interface of the arduinobot", "ament_cmake",
        [("depend", d) for d in ("rclcpp", "hardware_interface", "pluginlib",
                                 "rclcpp_lifecycle")]
        + [("exec_depend", d) for d in ("controller_manager", "ros2_controllers",
                                        "joint_state_broadcaster",
                                        "joint_trajectory_controller")]))
    _write(ctrl / "CMakeLists.txt", _cmake(CONTROLLER, "config"))
    _write(ctrl / "config" / "arduinobot_controllers.yaml", CONTROLLERS_YAML)

    _write(moveit / "package.xml", _manifest(
        MOVEIT, "An automatically generated package with all the configuration and launch "
        "files for using the arduinobot with the MoveIt Motion Planning Framework",
        "ament_cmake",
        [("exec_depend", d) for d in (
            "moveit_ros_move_group", "moveit_kinematics", "moveit_planners",
            "moveit_simple_controller_manager", "moveit_configs_utils",
            "moveit_ros_visualization", "moveit_setup_assistant", DESCRIPTION,
            "controller_manager", "rviz2", "xacro")]))
    _write(moveit / "CMakeLists.txt", _cmake(MOVEIT, "config"))
    _write(moveit / ".setup_assistant", SETUP_ASSISTANT)
    cfg = moveit / "config"
    _write(cfg / "arduinobot.srdf", srdf())
    _write(cfg / "joint_limits.yaml", joint_limits_yaml())
    _write(cfg / "kinematics.yaml", KINEMATICS_YAML)
    _write(cfg / "initial_positions.yaml", INITIAL_POSITIONS_YAML)
    _write(cfg / "moveit_controllers.yaml", MOVEIT_CONTROLLERS_YAML)
    _write(cfg / "pilz_cartesian_limits.yaml", PILZ_YAML)

    return CourseWorkspace(src=src, description_pkg=desc, controller_pkg=ctrl,
                           moveit_pkg=moveit, xacro=urdf / "arduinobot.urdf.xacro")


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or args[0].startswith("-"):
        print("usage: python -m tests.helpers.course_workspace OUT_DIR", file=sys.stderr)
        return 2
    ws = make_course_workspace(Path(args[0]).resolve())
    for name in ("src", "description_pkg", "controller_pkg", "moveit_pkg", "xacro"):
        print(f"{name}: {getattr(ws, name)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
