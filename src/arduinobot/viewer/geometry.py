"""What the viewer draws, without drawing it: link meshes, colours, obstacles, framing.

Pure numpy/trimesh, so it is testable without a browser or the viewer library.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from arduinobot.description import Description
from arduinobot.description.meshes import concatenate, load_mesh, shape_mesh
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.scene.obstacles import Obstacle

Rgb = tuple[int, int, int]

# Distinct, mid-bright colours that read on a white page. None of them is red-dominant,
# so a red pixel on screen always means "in collision".
PALETTE: tuple[Rgb, ...] = (
    (105, 115, 130),   # slate
    (60, 125, 205),    # blue
    (235, 180, 40),    # amber
    (40, 165, 150),    # teal
    (140, 95, 200),    # purple
    (95, 175, 75),     # green
    (150, 200, 60),    # lime
    (70, 180, 225),    # sky
    (190, 150, 95),    # tan
    (120, 120, 200),   # lavender
)
COLLISION_RGB: Rgb = (225, 25, 25)
OBSTACLE_RGB: Rgb = (150, 145, 135)
#: the kept scene's objects: a warmer grey than a request's own obstacles
SCENE_RGB: Rgb = (170, 150, 120)
#: an object the robot carries (magenta: neither a link colour nor collision red)
CARRIED_RGB: Rgb = (200, 60, 200)


@dataclass(frozen=True)
class LinkMesh:
    """One link's visual shapes merged into one mesh in the link frame [m]."""

    link: str
    index: int
    vertices: np.ndarray  # shape (n, 3), float32
    faces: np.ndarray  # shape (m, 3), uint32
    color: Rgb


@dataclass(frozen=True)
class CameraView:
    """A camera pose that frames a box: position and look-at point [m], vertical fov [rad]."""

    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    fov: float


def link_meshes(description: Description, kin: Kinematics) -> tuple[LinkMesh, ...]:
    """Every link with visuals (collision shapes if it has none), coloured in tree order."""
    out: list[LinkMesh] = []
    for i, name in enumerate(kin.link_names):
        link = description.robot.links[name]
        shapes = link.visuals or link.collisions
        if not shapes:
            continue
        parts = [shape_mesh(s, element=f"link '{name}'") for s in shapes]
        mesh = concatenate(parts) if len(parts) > 1 else parts[0]
        out.append(LinkMesh(link=name, index=i,
                            vertices=np.asarray(mesh.vertices, dtype=np.float32),
                            faces=np.asarray(mesh.faces, dtype=np.uint32),
                            color=PALETTE[len(out) % len(PALETTE)]))
    return tuple(out)


def obstacle_mesh(obstacle: Obstacle) -> trimesh.Trimesh:
    """An obstacle's triangles in its own frame [m] (a file: loaded once, as a link's)."""
    source = obstacle.geometry.source
    if source is not None:
        return load_mesh(source, obstacle.geometry.source_scale,
                         element=f"obstacle '{obstacle.id}'")
    return obstacle.geometry.triangles()


def world_bounds(meshes: Sequence[LinkMesh], poses: np.ndarray,
                 obstacles: Sequence[Obstacle] = (), *,
                 extra: Sequence[np.ndarray] = ()) -> np.ndarray:
    """Axis-aligned box of the links at ``poses`` (n_links, 4, 4), the obstacles and
    ``extra`` points (each shape (n, 3), in the world [m]), shape (2, 3) [m]."""
    pts = [m.vertices @ poses[m.index][:3, :3].T + poses[m.index][:3, 3] for m in meshes]
    for o in obstacles:
        pts.append(np.asarray(obstacle_mesh(o).copy().apply_transform(o.pose()).vertices))
    pts += [np.asarray(p, float) for p in extra]
    if not pts:
        return np.array([[-0.5, -0.5, 0.0], [0.5, 0.5, 1.0]])
    allp = np.concatenate(pts)
    return np.stack([allp.min(axis=0), allp.max(axis=0)])


def frame_box(bounds: np.ndarray, *, fov: float = math.radians(45.0), aspect: float = 1.6,
              direction: Sequence[float] = (1.0, 0.55, 0.45), fill: float = 0.9,
              left: float = 0.2) -> CameraView:
    """A camera on ``direction`` from the box centre, +z up, as close as it can be with
    every corner of the box inside ``fill`` of the field of view (vertical ``fov`` [rad],
    width/height ``aspect``), the box shifted ``left`` of the half-width to the left
    (the page's control panel floats over the right)."""
    lo, hi = np.asarray(bounds[0], float), np.asarray(bounds[1], float)
    centre = (lo + hi) / 2.0
    back = np.asarray(direction, float)
    back = back / np.linalg.norm(back)  # from the centre towards the camera
    right = np.cross((0.0, 0.0, 1.0), back)
    right = right / (np.linalg.norm(right) or 1.0)
    up = np.cross(back, right)
    tan_v = math.tan(fov / 2.0) * fill
    tan_h = tan_v * aspect * (1.0 - left)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])]) - centre
    # A corner at depth a towards the camera, offsets u (right) and v (up), fits when
    # |v| <= (dist - a) tan_v and |u| <= (dist - a) tan_h.
    a, u, v = corners @ back, corners @ right, corners @ up
    dist = float(np.max(a + np.maximum(np.abs(v) / tan_v, np.abs(u) / tan_h)))
    dist = max(dist, 1e-3)
    target = centre + right * (dist * math.tan(fov / 2.0) * aspect * left)
    pos = target + back * dist
    return CameraView(position=(float(pos[0]), float(pos[1]), float(pos[2])),
                      look_at=(float(target[0]), float(target[1]), float(target[2])), fov=fov)


def matrix_to_wxyz(rot: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z) of a rotation matrix, shape (3, 3)."""
    t = np.eye(4)
    t[:3, :3] = rot
    q = trimesh.transformations.quaternion_from_matrix(t, isprecise=True)
    return float(q[0]), float(q[1]), float(q[2]), float(q[3])


# blue (low) through teal and yellow to red (high): a height reads at a glance
_HEIGHT_STOPS = np.array([[40, 60, 200], [30, 170, 170], [240, 210, 40], [210, 50, 40]],
                         float)


def height_colors(z: np.ndarray) -> np.ndarray:
    """Colours for heights ``z`` (shape (n,) [m]): the lowest blue, the highest red,
    shape (n, 3) uint8 (all one colour where every height is the same)."""
    z = np.asarray(z, float)
    if len(z) == 0:
        return np.empty((0, 3), np.uint8)
    span = float(z.max() - z.min())
    t = (z - z.min()) / span if span > 0 else np.zeros(len(z))
    x = t * (len(_HEIGHT_STOPS) - 1)
    i = np.minimum(x.astype(int), len(_HEIGHT_STOPS) - 2)
    f = (x - i)[:, None]
    return np.round(_HEIGHT_STOPS[i] * (1 - f) + _HEIGHT_STOPS[i + 1] * f).astype(np.uint8)

