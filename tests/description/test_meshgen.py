"""Checks of the committed arduinobot meshes against the model's envelopes and kinematics.

The envelope numbers are the "Mesh envelopes" table of the robot model, copied
here on purpose: they are the spec the generator must meet.  Link poses come
from the expanded xacro (not from the generator), so a mesh that fits only
the generator's own idea of the origins still fails.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterator
from functools import cache, lru_cache
from pathlib import Path

import fcl
import numpy as np
import pytest
import trimesh
import xacro

from arduinobot.description import meshgen

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "arduinobot" / "description" / "arduinobot_description"
XACRO_FILE = PACKAGE / "urdf" / "arduinobot.urdf.xacro"
MESH_DIR = PACKAGE / "meshes"

Point = tuple[float, float, float]
Box = tuple[Point, Point]

# mesh file -> (file-frame box [cm], link-frame box [m]).
ENVELOPES: dict[str, tuple[Box, Box]] = {
    "basement.STL": (
        ((0.5, 0.5, 0.0), (95.1, 88.0, 31.0)),
        ((-0.495, -0.495, 0.0), (0.451, 0.38, 0.31)),
    ),
    "base_plate.STL": (
        ((0.0, 0.0, 56.6), (72.0, 76.6, 113.7)),
        ((-0.39, -0.39, 0.006), (0.33, 0.376, 0.577)),
    ),
    "forward_drive_arm.STL": (
        ((0.1, 0.2, 0.1), (92.5, 29.2, 15.1)),
        ((-0.102, -0.091, -0.079), (0.188, 0.059, 0.845)),
    ),
    "horizontal_arm.STL": (
        ((0.1, 0.1, 0.0), (127.6, 15.1, 8.0)),
        ((-0.03, -0.399, -0.059), (0.05, 0.876, 0.091)),
    ),
    "claw_support.STL": (
        ((0.1, 0.1, 0.1), (54.1, 25.1, 38.4)),
        ((-0.251, -0.049, -0.149), (-0.001, 0.491, 0.234)),
    ),
    "right_finger.STL": (
        ((0.0, 0.0, 0.0), (58.4, 14.0, 9.0)),
        ((-0.1, -0.084, -0.1), (0.04, 0.5, -0.01)),
    ),
    "left_finger.STL": (
        ((0.0, 0.1, 0.0), (58.4, 14.6, 9.0)),
        ((-0.039, -0.084, -0.1), (0.106, 0.5, -0.01)),
    ),
}
# The spec allows 0.5 cm per face.  The meshes are held to 0.15 cm: every
# face is on its table value except the basement's top and the turntable's
# underside, each moved 1 mm apart to widen the gap between them.
FILE_TOL_CM = 0.15
LINK_TOL_M = 0.0015
LARGE_PARTS = ("basement.STL", "base_plate.STL", "forward_drive_arm.STL", "horizontal_arm.STL")
MIN_CLEARANCE_M = 0.002
SWEEP_STEP_DEG = 5.0


# ------------------------------------------------------------------ model


def _floats(text: str | None, default: str) -> np.ndarray:
    return np.array([float(v) for v in (text or default).split()])


def _origin(elem: ET.Element | None) -> np.ndarray:
    if elem is None:
        return np.eye(4)
    xyz = _floats(elem.get("xyz"), "0 0 0")
    rpy = _floats(elem.get("rpy"), "0 0 0")
    transform = trimesh.transformations.euler_matrix(*rpy, "sxyz")
    transform[:3, 3] = xyz
    return transform


@lru_cache(maxsize=1)
def _robot() -> ET.Element:
    return ET.fromstring(xacro.process_file(str(XACRO_FILE)).toprettyxml(indent="  "))


@lru_cache(maxsize=1)
def _collisions() -> dict[str, tuple[str, np.ndarray, np.ndarray]]:
    """link -> (mesh file name, scale, collision origin)."""
    out: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
    for link in _robot().findall("link"):
        collision = link.find("collision")
        if collision is None:
            continue
        mesh = _child(collision, "geometry/mesh")
        name = mesh.get("filename", "").rsplit("/", 1)[-1]
        scale = _floats(mesh.get("scale"), "1 1 1")
        out[link.get("name", "")] = (name, scale, _origin(collision.find("origin")))
    return out


def _child(elem: ET.Element, path: str) -> ET.Element:
    found = elem.find(path)
    assert found is not None, f"<{elem.tag} name={elem.get('name')!r}> has no <{path}>"
    return found


def _joint_angle(joint: ET.Element, q: dict[str, float]) -> float:
    mimic = joint.find("mimic")
    if mimic is None:
        return q.get(joint.get("name", ""), 0.0)
    leader = q.get(mimic.get("joint", ""), 0.0)
    return float(mimic.get("multiplier", "1")) * leader + float(mimic.get("offset", "0"))


def _forward_kinematics(q: dict[str, float]) -> dict[str, np.ndarray]:
    """World pose of every link for joint angles ``q`` [rad] (missing joints at 0)."""
    joint_of = {_child(j, "child").get("link"): j for j in _robot().findall("joint")}
    poses: dict[str, np.ndarray] = {}

    def pose(link: str) -> np.ndarray:
        if link not in poses:
            joint = joint_of.get(link)
            if joint is None:
                poses[link] = np.eye(4)
            else:
                parent = pose(_child(joint, "parent").get("link", ""))
                transform = parent @ _origin(joint.find("origin"))
                if joint.get("type") in ("revolute", "continuous"):
                    axis = _floats(_child(joint, "axis").get("xyz"), "1 0 0")
                    rotation = trimesh.transformations.rotation_matrix(_joint_angle(joint, q), axis)
                    transform = transform @ rotation
                poses[link] = transform
        return poses[link]

    for link in _robot().findall("link"):
        pose(link.get("name", ""))
    return poses


def _limits(joint_name: str) -> tuple[float, float]:
    for joint in _robot().findall("joint"):
        if joint.get("name") == joint_name:
            limit = _child(joint, "limit")
            return float(limit.get("lower", "0")), float(limit.get("upper", "0"))
    raise KeyError(joint_name)


def _sweep(joint_name: str) -> Iterator[float]:
    lower, upper = _limits(joint_name)
    count = int(np.ceil((upper - lower) / np.radians(SWEEP_STEP_DEG))) + 1
    yield from np.linspace(lower, upper, count)


# ----------------------------------------------------------------- meshes


@cache
def _file_mesh(name: str) -> trimesh.Trimesh:
    mesh = trimesh.load(MESH_DIR / name, force="mesh")
    assert isinstance(mesh, trimesh.Trimesh)
    return mesh


def _link_vertices(link: str) -> tuple[np.ndarray, np.ndarray]:
    name, scale, origin = _collisions()[link]
    mesh = _file_mesh(name)
    vertices = trimesh.transform_points(mesh.vertices * scale, origin)
    return vertices, np.asarray(mesh.faces)


@cache
def _bvh(link: str) -> fcl.BVHModel:
    vertices, faces = _link_vertices(link)
    model = fcl.BVHModel()
    model.beginModel(len(vertices), len(faces))
    model.addSubModel(vertices, faces)
    model.endModel()
    return model


def _clearance(link_a: str, link_b: str, poses: dict[str, np.ndarray]) -> float:
    """Minimum distance [m] between two links' collision meshes, -1 if they intersect."""
    objects = [
        fcl.CollisionObject(_bvh(link), fcl.Transform(poses[link][:3, :3], poses[link][:3, 3]))
        for link in (link_a, link_b)
    ]
    if fcl.collide(*objects, fcl.CollisionRequest(), fcl.CollisionResult()):
        return -1.0
    return float(fcl.distance(*objects, fcl.DistanceRequest(), fcl.DistanceResult()))


# ------------------------------------------------------------------ tests


def test_every_link_uses_a_generated_mesh() -> None:
    assert sorted(name for name, _, _ in _collisions().values()) == sorted(ENVELOPES)
    assert sorted(meshgen.PARTS) == sorted(ENVELOPES)


@pytest.mark.parametrize("name", sorted(ENVELOPES))
def test_file_frame_bounds_match_envelope(name: str) -> None:
    (lo, hi), _ = ENVELOPES[name]
    bounds = _file_mesh(name).bounds
    np.testing.assert_allclose(bounds[0], lo, atol=FILE_TOL_CM)
    np.testing.assert_allclose(bounds[1], hi, atol=FILE_TOL_CM)


@pytest.mark.parametrize("link", sorted(_collisions()))
def test_link_frame_bounds_match_envelope(link: str) -> None:
    name = _collisions()[link][0]
    _, (lo, hi) = ENVELOPES[name]
    vertices, _ = _link_vertices(link)
    np.testing.assert_allclose(vertices.min(axis=0), lo, atol=LINK_TOL_M)
    np.testing.assert_allclose(vertices.max(axis=0), hi, atol=LINK_TOL_M)


@pytest.mark.parametrize("name", sorted(ENVELOPES))
def test_mesh_is_a_clean_closed_solid(name: str) -> None:
    mesh = _file_mesh(name)
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.volume > 0.0
    bodies = mesh.split(only_watertight=False)
    assert 1 <= len(bodies) <= 3
    assert all(body.is_watertight for body in bodies)


def test_files_are_binary_stl() -> None:
    for name in ENVELOPES:
        data = (MESH_DIR / name).read_bytes()
        triangles = int.from_bytes(data[80:84], "little")
        assert len(data) == 84 + 50 * triangles


@pytest.mark.parametrize("name", sorted(ENVELOPES))
def test_meshes_are_finely_tessellated(name: str) -> None:
    minimum = 2000 if name in LARGE_PARTS else 1000
    assert len(_file_mesh(name).faces) >= minimum


def test_no_two_links_touch_at_zero_pose() -> None:
    poses = _forward_kinematics({})
    links = sorted(_collisions())
    too_close = {
        (a, b): d
        for i, a in enumerate(links)
        for b in links[i + 1 :]
        if (d := _clearance(a, b, poses)) < MIN_CLEARANCE_M
    }
    assert not too_close


@pytest.mark.parametrize(
    ("joint", "pairs"),
    [
        ("joint_1", [("base_link", "base_plate")]),
        ("joint_2", [("base_plate", "forward_drive_arm")]),
        ("joint_3", [("forward_drive_arm", "horizontal_arm")]),
        (
            "joint_4",
            [
                ("claw_support", "gripper_right"),
                ("claw_support", "gripper_left"),
                ("gripper_right", "gripper_left"),
            ],
        ),
    ],
)
def test_adjacent_links_stay_apart_over_joint_range(
    joint: str, pairs: list[tuple[str, str]]
) -> None:
    failures = []
    for angle in _sweep(joint):
        poses = _forward_kinematics({joint: float(angle)})
        for a, b in pairs:
            if (d := _clearance(a, b, poses)) < MIN_CLEARANCE_M:
                failures.append((a, b, round(float(np.degrees(angle)), 1), d))
    assert not failures


def test_own_kinematics_agree_with_yourdfpy(tmp_path: Path) -> None:
    import yourdfpy

    urdf_file = tmp_path / "arduinobot.urdf"
    urdf_file.write_text(ET.tostring(_robot(), encoding="unicode"))
    robot = yourdfpy.URDF.load(str(urdf_file), load_meshes=False, load_collision_meshes=False)
    q = {"joint_1": 0.3, "joint_2": -0.7, "joint_3": 1.1, "joint_4": -0.5}
    robot.update_cfg(q)
    ours = _forward_kinematics(q)
    for link in _collisions():
        np.testing.assert_allclose(robot.get_transform(link, "world"), ours[link], atol=1e-9)


def test_generator_reproduces_committed_files(tmp_path: Path) -> None:
    meshes = meshgen.generate(tmp_path)
    assert sorted(meshes) == sorted(ENVELOPES)
    for name in ENVELOPES:
        assert (tmp_path / name).read_bytes() == (MESH_DIR / name).read_bytes(), name
