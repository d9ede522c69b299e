"""A 7-joint arm with CAD-like meshes, generated: for clutter tests and the speed work.

The kinematics are those of a common 7-joint research arm (revolute joints with
alternating +-90 degree twists, 0.333/0.316/0.384 m segments, 0.0825 m offsets, reach
about 0.85 m); every link is a mesh of ours: a joint housing (a cylinder about its
joint's axis) and a capsule to the next joint, a few thousand triangles each, written as
millimetre STL and scaled back by the URDF's ``scale="0.001 0.001 0.001"`` (as CAD exports
are). A fixed ``flange`` and a massless ``tool0`` frame on a fixed joint end the chain.
The SRDF names the ``arm`` group, a ``ready`` state and disables the pairs a joint
connects and two wrist pairs whose housings touch at (almost) every angle.

:func:`make_seven_joint` writes the package; tests/helpers/mbm_scenes.py's
``problems_for`` makes shelf, cage, box and table problems for it (``tip="tool0"``,
``reach=0.85``), as tests/service/test_seven_joint_clutter.py does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

NAME = "seven_bot"
HALF_PI = 1.5707963267948966
#: (name, parent, child, xyz, rpy, lower, upper, velocity [rad/s], effort [N m])
JOINTS = [
    ("joint1", "link0", "link1", (0, 0, 0.333), (0, 0, 0), -2.9, 2.9, 2.2, 87),
    ("joint2", "link1", "link2", (0, 0, 0), (-HALF_PI, 0, 0), -1.76, 1.76, 2.2, 87),
    ("joint3", "link2", "link3", (0, -0.316, 0), (HALF_PI, 0, 0), -2.9, 2.9, 2.2, 87),
    ("joint4", "link3", "link4", (0.0825, 0, 0), (HALF_PI, 0, 0), -3.07, -0.07, 2.2, 87),
    ("joint5", "link4", "link5", (-0.0825, 0.384, 0), (-HALF_PI, 0, 0), -2.9, 2.9, 2.6, 12),
    ("joint6", "link5", "link6", (0, 0, 0), (HALF_PI, 0, 0), -0.02, 3.75, 2.6, 12),
    ("joint7", "link6", "link7", (0.088, 0, 0), (HALF_PI, 0, 0), -2.9, 2.9, 2.6, 12),
]
FLANGE = (0, 0, 0.107)
TOOL = (0, 0, 0.1)
READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
#: per link: (housing radius, housing length, capsule radius) [m]
SIZES = {"link0": (0.07, 0.1, 0.07), "link1": (0.055, 0.12, 0.055),
         "link2": (0.055, 0.12, 0.035), "link3": (0.05, 0.11, 0.05),
         "link4": (0.045, 0.11, 0.045), "link5": (0.045, 0.1, 0.04),
         "link6": (0.04, 0.09, 0.04), "link7": (0.04, 0.08, 0.035),
         "flange": (0.045, 0.02, 0.03)}
MASSES = {"link0": 4.0, "link1": 3.0, "link2": 3.0, "link3": 2.5, "link4": 2.5,
          "link5": 2.0, "link6": 1.5, "link7": 0.5, "flange": 0.3}
#: wrist pairs whose housings touch at (almost) every angle: in 300 seeded random states
#: link4-link6 collided in all, link5-link7 in 280 (as MoveIt's "Always" pairs)
EXTRA_DISABLED = [("link4", "link6"), ("link5", "link7")]


def _capsule(a: np.ndarray, b: np.ndarray, r: float) -> trimesh.Trimesh:
    """A capsule of radius ``r`` from ``a`` to ``b`` (a sphere if they coincide)."""
    v = b - a
    h = float(np.linalg.norm(v))
    if h < 1e-6:
        m = trimesh.creation.icosphere(subdivisions=3, radius=r)
        m.apply_translation(a)
        return m
    m = trimesh.creation.capsule(height=h, radius=r, count=[32, 32])
    m.apply_translation([0, 0, h / 2])  # base at the origin, along +z
    m.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], v / h))
    m.apply_translation(a)
    return m


def link_mesh(link: str) -> trimesh.Trimesh:
    """``link``'s mesh in metres, in its own frame."""
    hr, hl, cr = SIZES[link]
    housing = trimesh.creation.cylinder(radius=hr, height=hl, sections=48)
    parts = [housing]
    nxt = {parent: np.array(xyz, float) for _, parent, _, xyz, *_ in JOINTS}
    nxt["link7"] = np.array(FLANGE, float)
    if link == "link0":
        housing.apply_translation([0, 0, hl / 2])
        parts.append(_capsule(np.zeros(3), np.array([0, 0, 0.14]), cr))
    elif link == "link1":
        parts.append(_capsule(np.array([0, 0, -0.2]), np.zeros(3), cr))
    elif link == "link5":  # the forearm's far half turns with joint 5
        parts.append(_capsule(np.zeros(3), np.array([0, 0, -0.2]), cr))
    elif link == "flange":
        housing.apply_translation([0, 0, -hl / 2])
    if link != "link0" and link in nxt and float(np.linalg.norm(nxt[link])) > 1e-6:
        parts.append(_capsule(np.zeros(3), nxt[link], cr))
    return trimesh.util.concatenate(parts)


def _inertial(mass: float) -> str:
    i = 0.01 * mass
    return (f'<inertial><mass value="{mass}"/><inertia ixx="{i}" ixy="0" ixz="0" '
            f'iyy="{i}" iyz="0" izz="{i}"/></inertial>')


def urdf_text() -> str:
    links = []
    for link in SIZES:
        mesh = f'<mesh filename="package://{NAME}_description/meshes/{link}.stl" ' \
               f'scale="0.001 0.001 0.001"/>'
        links.append(f'  <link name="{link}">\n    <visual><geometry>{mesh}</geometry></visual>\n'
                     f'    <collision><geometry>{mesh}</geometry></collision>\n'
                     f'    {_inertial(MASSES[link])}\n  </link>\n')
    links.append('  <link name="tool0"/>\n')  # massless, on a fixed joint
    joints = []
    for name, parent, child, xyz, rpy, lo, hi, vel, eff in JOINTS:
        joints.append(
            f'  <joint name="{name}" type="revolute">\n    <parent link="{parent}"/>'
            f'<child link="{child}"/>\n    <origin xyz="{" ".join(map(str, xyz))}" '
            f'rpy="{" ".join(map(str, rpy))}"/><axis xyz="0 0 1"/>\n'
            f'    <limit lower="{lo}" upper="{hi}" velocity="{vel}" effort="{eff}"/>\n'
            f'  </joint>\n')
    joints.append(f'  <joint name="flange_joint" type="fixed"><parent link="link7"/>'
                  f'<child link="flange"/><origin xyz="{" ".join(map(str, FLANGE))}"/>'
                  f'</joint>\n')
    joints.append(f'  <joint name="tool0_joint" type="fixed"><parent link="flange"/>'
                  f'<child link="tool0"/><origin xyz="{" ".join(map(str, TOOL))}"/></joint>\n')
    return f'<?xml version="1.0"?>\n<robot name="{NAME}">\n' + "".join(links + joints) \
        + "</robot>\n"


def srdf_text() -> str:
    pairs = [(p, c) for _, p, c, *_ in JOINTS] + [("link7", "flange")] + EXTRA_DISABLED
    ready = "".join(f'<joint name="joint{i + 1}" value="{v}"/>' for i, v in enumerate(READY))
    body = "".join(f'  <disable_collisions link1="{a}" link2="{b}" reason="Adjacent"/>\n'
                   for a, b in pairs)
    return (f'<?xml version="1.0"?>\n<robot name="{NAME}">\n'
            f'  <group name="arm"><chain base_link="link0" tip_link="tool0"/></group>\n'
            f'  <group_state name="ready" group="arm">{ready}</group_state>\n'
            f'{body}</robot>\n')


def make_seven_joint(root: Path) -> Path:
    """Write the ``seven_bot_description`` package under ``root`` (URDF, millimetre STL
    meshes, ``config/seven_bot.srdf``); the URDF's path."""
    pkg = root / f"{NAME}_description"
    (pkg / "meshes").mkdir(parents=True, exist_ok=True)
    (pkg / "urdf").mkdir(exist_ok=True)
    (pkg / "config").mkdir(exist_ok=True)
    (pkg / "package.xml").write_text(
        f'<?xml version="1.0"?>\n<package format="3"><name>{NAME}_description</name>'
        '<version>0.0.1</version><description>generated test arm</description>'
        '<maintainer email="t@example.com">t</maintainer><license>MIT</license></package>\n')
    for link in SIZES:
        m = link_mesh(link)
        m.apply_scale(1000.0)  # millimetres, as CAD exports
        m.export(pkg / "meshes" / f"{link}.stl")
    urdf = pkg / "urdf" / f"{NAME}.urdf"
    urdf.write_text(urdf_text())
    (pkg / "config" / f"{NAME}.srdf").write_text(srdf_text())
    return urdf
