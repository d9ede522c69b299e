"""The robot's collision geometry, built once per description: each link's mesh as an
OBB tree (:mod:`.obbtree`), an FCL BVH, a convex hull (:mod:`.hulls`) and, on first use,
its part hulls (:mod:`.parts`).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, TypeVar, cast

import fcl
import numpy as np
import trimesh

from arduinobot.description import Description
from arduinobot.description.meshes import shape_mesh
from arduinobot.planner.cache import ArtifactCache
from arduinobot.planner.collision.bounds.hulls import Hull, mesh_hull
from arduinobot.planner.collision.bounds.obbtree import ObbTree, cached_tree
from arduinobot.planner.collision.bounds.parts import Parts, mesh_parts
from arduinobot.planner.kinematics.chain import Kinematics

_T = TypeVar("_T")


def bvh(mesh: trimesh.Trimesh) -> fcl.BVHModel:
    """FCL's BVH of a triangle mesh, in the mesh's frame."""
    m = fcl.BVHModel()
    m.beginModel(len(mesh.vertices), len(mesh.faces))
    m.addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
    m.endModel()
    return m


class ShapeCache:
    """Scene shapes' collision geometry by content, least recently used dropped past
    ``max_items``: a world for a new obstacle set (a scene's next revision) reuses what an
    earlier one built for the same mesh instead of loading it again (~0.4 s for a mesh of
    10k triangles)."""

    def __init__(self, max_items: int = 64) -> None:
        self.max_items = max_items
        self._items: dict[Hashable, object] = {}

    def get(self, key: Hashable, build: Callable[[], _T]) -> _T:
        """The geometry under ``key``, built by ``build()`` the first time."""
        found = self._items.pop(key, None)
        if found is None:
            found = build()
        self._items[key] = found  # most recently used last
        while len(self._items) > self.max_items:
            self._items.pop(next(iter(self._items)))
        return cast(_T, found)

    def __len__(self) -> int:
        return len(self._items)


@dataclass(frozen=True, eq=False)
class RobotBodies:
    """The robot's collision geometry, built once per description and shared by every
    world of it: a world per obstacle set would otherwise rebuild each link's OBB tree
    and BVH (~1.5 s for the shipped meshes, ~13 s at 50k triangles a link).

    Attributes:
        names: the links that have collision geometry, in FK order.
        frames: each one's index in ``Kinematics.link_names``.
        trees: each one's OBB tree (link frame).
        geometries: each one's FCL BVH (link frame); shared, never moved.
        statics: whether the link never moves (no movable joint above it).
        points: (link, vertices) for the motion bounds.
        hulls: each one's convex hull (link frame), for cheap distance bounds.
        faces: each one's triangles (shape (f, 3), into its ``points``' vertices), for
            its part hulls (:meth:`parts_of`).
        shapes: the scene shapes' geometry built so far, by content, for every world
            of the robot.
        proofs: what proofs keep for every world of the robot, by kind (the
            one-dimensional pairs' cells: :class:`.one_dim.PairCells`).
        cache: where artifacts are kept between runs by content (the trees and hulls
            were read from it; the one-dimensional pairs' cells and the part hulls are
            kept there), if anywhere.
        split: False: every link keeps its hull alone, never split into parts (to
            measure what the parts buy).
    """

    description: Description
    names: tuple[str, ...]
    frames: tuple[int, ...]
    trees: tuple[ObbTree, ...]
    geometries: tuple[fcl.BVHModel, ...]
    statics: tuple[bool, ...]
    points: tuple[tuple[str, np.ndarray], ...]
    hulls: tuple[Hull, ...]
    faces: tuple[np.ndarray, ...]
    shapes: ShapeCache = field(default_factory=ShapeCache, repr=False)
    proofs: dict[str, Any] = field(default_factory=dict, repr=False)
    cache: ArtifactCache | None = field(default=None, repr=False, compare=False)
    split: bool = field(default=True, compare=False)
    _parts: dict[int, Parts] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(cls, description: Description, kin: Kinematics, *,
              cache: ArtifactCache | None = None) -> RobotBodies:
        """Build every link's geometry; trees and hulls come from ``cache`` when it has
        them, and with a cache the links' part hulls too (from it, else built now:
        without one they are built on first use, :meth:`parts_of`)."""
        robot = description.robot
        names, frames, trees, geoms, statics, points, hulls = [], [], [], [], [], [], []
        faces: list[np.ndarray] = []
        for link in kin.link_names:
            shapes = robot.links[link].collisions
            if not shapes:
                continue
            meshes = [shape_mesh(s, element=f"link '{link}' collision") for s in shapes]
            # concatenate is annotated as returning any Geometry: of meshes it is a mesh
            mesh = meshes[0] if len(meshes) == 1 else cast(
                "trimesh.Trimesh", trimesh.util.concatenate(meshes))
            names.append(link)
            frames.append(kin.link_index[link])
            trees.append(cached_tree(mesh.vertices, mesh.faces, cache))
            geoms.append(bvh(mesh))
            statics.append(not any(j.movable for j in robot.link_path(link)))
            points.append((link, np.asarray(mesh.vertices, float)))
            hulls.append(mesh_hull(points[-1][1], cache))
            faces.append(np.asarray(mesh.faces, np.int64))
        bodies = cls(description, tuple(names), tuple(frames), tuple(trees), tuple(geoms),
                     tuple(statics), tuple(points), tuple(hulls), tuple(faces), cache=cache)
        if cache is not None:
            # a long-lived caller (the service's zygote, before it forks its workers):
            # every link's parts now, read from the cache after the first start, rather
            # than seconds into the first plan near a concave link
            for i in range(len(names)):
                bodies.parts_of(i)
        return bodies

    def parts_of(self, i: int) -> Parts:
        """Link ``i``'s part hulls (:func:`.parts.mesh_parts`), built on first use (1-3
        s for a concave CAD link of 20-50k triangles; most worlds without a cache never
        need them) and kept for every world of the robot, and in ``cache``."""
        if not self.split:
            return Parts.of_hull(self.hulls[i])
        found = self._parts.get(i)
        if found is None:
            found = self._parts[i] = mesh_parts(self.points[i][1], self.faces[i],
                                                self.hulls[i], self.cache)
        return found
