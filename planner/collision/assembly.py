"""Assembling a world's bodies: the robot's links (shared, :mod:`.bodies`) and the
scene's obstacles, in the body table's order, with what each needs (OBB tree, FCL
object, convex hull, the points its motion bounds read), and the pairs worth checking.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import cast

import fcl
import numpy as np
import trimesh

from ..scene import Obstacle
from .acm import AllowedCollisionMatrix
from .bodies import RobotBodies, bvh
from .hulls import Hull, mesh_hull, primitive_hull
from .obbtree import ObbTree, box_tree, build_tree
from .table import BodyKind, checked_kinds


def _obstacle_geometry(o: Obstacle) -> tuple[fcl.CollisionGeometry, ObbTree, Hull]:
    # Obstacle checked that its shape's dimensions (or mesh file) are set
    if o.shape == "box":
        assert o.size is not None
        return fcl.Box(*o.size), box_tree(np.asarray(o.size) / 2), primitive_hull(o)
    if o.shape == "sphere":
        assert o.radius is not None
        return fcl.Sphere(o.radius), box_tree(np.full(3, o.radius)), primitive_hull(o)
    if o.shape == "cylinder":
        assert o.radius is not None and o.length is not None
        return (fcl.Cylinder(o.radius, o.length),
                box_tree(np.array([o.radius, o.radius, o.length / 2])), primitive_hull(o))
    mesh = cast("trimesh.Trimesh", trimesh.load(o.mesh_path, force="mesh"))  # force: one mesh
    return (bvh(mesh), build_tree(mesh.vertices, mesh.faces),
            mesh_hull(np.asarray(mesh.vertices, float)))


@dataclass(frozen=True, eq=False)
class SceneBodies:
    """Every body of a world, in the table's order (the links, then the obstacles).

    Attributes:
        names, kinds: each body's name and :class:`.table.BodyKind`.
        links: the link index that moves each, -1 for an obstacle.
        trees: OBB trees (body frame).
        objects: FCL objects (an obstacle's placed, a link's moved per state).
        surfaces: a box obstacle's surface as 12 triangles, by body index, for distances
            at free states only (FCL's mesh-box distance is 2.5x slower than mesh-mesh on
            CAD links, measured).
        statics: whether a body never moves.
        points: (link name or None, vertices in its frame) for the motion bounds.
        hulls: convex hulls (body frame).
        poses: shape (n, 4, 4): an obstacle's world pose, identity for a link.
    """

    names: tuple[str, ...]
    kinds: tuple[BodyKind, ...]
    links: tuple[int, ...]
    trees: tuple[ObbTree, ...]
    objects: tuple[fcl.CollisionObject, ...]
    surfaces: dict[int, fcl.CollisionObject]
    statics: tuple[bool, ...]
    points: tuple[tuple[str | None, np.ndarray], ...]
    hulls: tuple[Hull, ...]
    poses: np.ndarray

    @classmethod
    def assemble(cls, robot: RobotBodies, obstacles: Sequence[Obstacle]) -> SceneBodies:
        """The robot's links (geometry shared, FCL objects new) and ``obstacles``."""
        names, links = list(robot.names), list(robot.frames)
        kinds = [BodyKind.LINK] * len(names)
        trees, statics = list(robot.trees), list(robot.statics)
        points: list[tuple[str | None, np.ndarray]] = list(robot.points)
        hulls = list(robot.hulls)
        objs = [fcl.CollisionObject(g, fcl.Transform()) for g in robot.geometries]
        surfaces: dict[int, fcl.CollisionObject] = {}
        poses = np.tile(np.eye(4), (len(names) + len(obstacles), 1, 1))
        for o in obstacles:
            geom, tree, hull = _obstacle_geometry(o)
            pose = o.pose()
            poses[len(names)] = pose
            names.append(o.id)
            links.append(-1)
            kinds.append(BodyKind.OBSTACLE)
            trees.append(tree)
            objs.append(fcl.CollisionObject(geom, fcl.Transform(pose[:3, :3], pose[:3, 3])))
            if o.shape == "box":
                surfaces[len(objs) - 1] = fcl.CollisionObject(
                    bvh(trimesh.creation.box(extents=o.size)),
                    fcl.Transform(pose[:3, :3], pose[:3, 3]))
            statics.append(True)
            points.append((None, np.zeros((1, 3))))
            hulls.append(hull)
        return cls(tuple(names), tuple(kinds), tuple(links), tuple(trees), tuple(objs),
                   surfaces, tuple(statics), tuple(points), tuple(hulls), poses)

    def checked_pairs(self, acm: AllowedCollisionMatrix
                      ) -> tuple[np.ndarray, tuple[tuple[int, int], ...]]:
        """The pairs to check, (a, b) with a < b: those some motion moves, shape (m, 2),
        and those of two bodies that never move (decided once). Skipped: pairs whose
        kinds never matter (:func:`.table.checked_kinds`) and the allowed ones."""
        moving: list[tuple[int, int]] = []
        fixed: list[tuple[int, int]] = []
        for a, b in combinations(range(len(self.names)), 2):
            if not checked_kinds(self.kinds[a], self.kinds[b]):
                continue
            if acm.allowed(self.names[a], self.names[b]):
                continue
            (fixed if self.statics[a] and self.statics[b] else moving).append((a, b))
        return np.array(moving, dtype=np.int64).reshape(-1, 2), tuple(fixed)
