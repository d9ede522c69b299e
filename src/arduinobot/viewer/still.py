"""A still picture of the page's 3D scene without a browser (``arduinobot view --png``):
the robot's links at one pose in their colours, the obstacles, the kept scene's objects
and what the robot carries on its link, drawn by matplotlib (the view extra).

All bodies are drawn as one shaded triangle collection, large triangles split first:
matplotlib sorts the polygons of a collection by depth, but whole collections only by
their centre, so a box standing on a table (one collection each) was hidden under it.
Painter's sorting is enough to read a scene, not to judge a contact (the page's
collision colours say that).
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.scene.obstacles import Obstacle
from arduinobot.viewer import require
from arduinobot.viewer.geometry import (
    CARRIED_RGB,
    OBSTACLE_RGB,
    SCENE_RGB,
    LinkMesh,
    Rgb,
    frame_box,
    obstacle_mesh,
)
from arduinobot.viewer.scene_view import ViewerScene

#: the light's direction (towards it), for the shading of each triangle
_LIGHT = np.array([0.4, 0.3, 1.0]) / np.linalg.norm([0.4, 0.3, 1.0])


@dataclass(frozen=True)
class StillBody:
    """One body as drawn: its triangles in the world, shape (m, 3, 3) [m], and colour."""

    name: str
    triangles: np.ndarray
    color: Rgb


def still_bodies(kin: Kinematics, meshes: Sequence[LinkMesh], q: np.ndarray, *,
                 obstacles: Sequence[Obstacle] = (), scene: ViewerScene | None = None,
                 moved: Mapping[str, np.ndarray] | None = None) -> list[StillBody]:
    """What the picture draws at pose ``q`` (shape (dof,) [rad]): the links, the
    obstacles (at ``moved``'s pose, shape (4, 4), for the ids it names: a task's carried
    box), the scene's free objects and its carried ones where their link is."""
    moved = moved or {}
    poses = kin.link_poses(np.asarray(q, float))
    out = [StillBody(m.link, _placed(m.vertices, m.faces, poses[m.index]), m.color)
           for m in meshes]
    for o in obstacles:
        mesh = obstacle_mesh(o)
        out.append(StillBody(o.id, _placed(mesh.vertices, mesh.faces, moved.get(o.id, o.pose())),
                             OBSTACLE_RGB))
    for item in scene.items if scene is not None else ():
        link = poses[kin.link_index[item.link]] if item.link is not None else None
        out.append(StillBody(item.id, _placed(item.vertices, item.faces, item.pose(link)),
                             CARRIED_RGB if item.carried else SCENE_RGB))
    return out


def _placed(vertices: np.ndarray, faces: np.ndarray, pose: np.ndarray) -> np.ndarray:
    v = np.asarray(vertices, float) @ pose[:3, :3].T + pose[:3, 3]
    return v[np.asarray(faces, int)]


def still_png(bodies: Sequence[StillBody], *, title: str = "", size: tuple[int, int] = (960, 720),
              dpi: int = 100) -> bytes:
    """The bodies as a PNG from the page's first camera (+z up, framed as the page
    frames them), ``size`` pixels."""
    matplotlib = require("matplotlib")
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure  # the OO API: no global pyplot state
    art3d = require("mpl_toolkits.mplot3d.art3d")

    pts = np.concatenate([b.triangles.reshape(-1, 3) for b in bodies]) if bodies \
        else np.zeros((1, 3))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    view = frame_box(np.stack([lo, hi]), aspect=size[0] / size[1], left=0.0)
    fig = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    ax = fig.add_subplot(projection="3d")
    half = float(np.max(hi - lo)) / 2 or 0.5
    if bodies:
        # one collection, so triangles are sorted across bodies; none longer than 1/40
        # of the view, so a table's two big top triangles do not sort as one far point
        tris, colors = _split(np.concatenate([b.triangles for b in bodies]),
                              np.concatenate([_shaded(b.triangles, b.color) for b in bodies]),
                              longest=half / 20)
        ax.add_collection3d(art3d.Poly3DCollection(tris, facecolors=colors,
                                                   edgecolors="none"))
    centre = (lo + hi) / 2
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    d = np.asarray(view.position) - np.asarray(view.look_at)
    ax.view_init(elev=float(np.degrees(np.arctan2(d[2], np.hypot(d[0], d[1])))),
                 azim=float(np.degrees(np.arctan2(d[1], d[0]))))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    if title:
        ax.set_title(title)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _split(triangles: np.ndarray, colors: np.ndarray, *, longest: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (shape (m, 3, 3) [m]) with an edge over ``longest`` [m] split in four at
    their edges' midpoints until none is (at most 8 rounds), each keeping its colour."""
    for _ in range(8):
        edges = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2).max(axis=1)
        big = edges > longest
        if not big.any():
            break
        t = triangles[big]
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        quads = np.stack([np.stack(x, axis=1) for x in
                          ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))], axis=1)
        triangles = np.concatenate([triangles[~big], quads.reshape(-1, 3, 3)])
        colors = np.concatenate([colors[~big], np.repeat(colors[big], 4, axis=0)])
    return triangles, colors


def _shaded(triangles: np.ndarray, color: Rgb) -> np.ndarray:
    """One RGBA per triangle: ``color`` lit by a fixed light (two-sided), shape (m, 4)."""
    n = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    light = 0.45 + 0.55 * np.abs(n @ _LIGHT)
    rgb = np.clip(np.asarray(color, float)[None, :] / 255.0 * light[:, None], 0.0, 1.0)
    return np.concatenate([rgb, np.ones((len(rgb), 1))], axis=1)
