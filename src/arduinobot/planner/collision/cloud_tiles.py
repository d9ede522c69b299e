"""A cloud body's FCL geometry in tiles, each tile's BVH built the first time a query
comes near it.

The union of a cloud's cells is bounded by its exposed faces
(:func:`.cloud_body.exposed_faces`). FCL builds a BVH per triangle: 2.8 s for the ~330k
triangles of a 300,000-point table and pillar at 1 cm (bench/cloud.py), nearly all of it
spent on faces the arm never comes near. Here the cells are cut into tiles of
:data:`TILE` cells along each axis; a tile's faces are its cells' faces without an
occupied neighbour (looked up among all the cells, so a face between two tiles is inside
the union and in neither), its own BVH, built on the first query within reach of the
tile's box. The tiles' faces together are exactly the union's boundary, so:

- a body collides with the boundary iff it collides with some tile's faces, and only
  the tiles whose boxes its box touches can;
- the distance to the union is the least over the tiles, and a tile's box bounds its
  faces' distance from below: tiles are asked nearest box first, and those whose box is
  farther than the best distance found are skipped, never built.

The built tiles stay with the geometry, which a worker keeps by the cells' content
(:class:`.bodies.ShapeCache`): every later world of the same cloud reuses them.
"""

from __future__ import annotations

import fcl
import numpy as np

from arduinobot.planner.collision.bounds.hulls import Hull
from arduinobot.planner.collision.bounds.obbtree import ObbTree
from arduinobot.planner.collision.cloud_body import (
    cell_hull,
    cell_tree,
    exposed_faces,
    surface_bvh,
)
from arduinobot.scene.cloud import Cells

#: Cells along each axis of a tile: ~1-5k triangles a tile for a measured surface
#: (~10-30 ms to build), few enough that an arm near a table builds a handful.
TILE = 16


class CloudSurface:
    """The boundary of a cloud's cells (world frame) as tiles of FCL BVHs.

    Attributes:
        cells: the cells.
        lo, hi: each tile's box (its cells' extent), shape (t, 3) [m].
        built: how many tiles' BVHs were built so far.
    """

    def __init__(self, cells: Cells) -> None:
        if len(cells) == 0:
            raise ValueError("a cloud body needs at least one cell")
        self.cells = cells
        tile = np.floor_divide(cells.index, TILE)
        tile -= tile.min(axis=0)  # < 2^21 along each axis, as the cells' (cloud.voxelise)
        key = (tile[:, 0] << 42) | (tile[:, 1] << 21) | tile[:, 2]
        order = np.argsort(key, kind="stable")
        key = key[order]
        starts = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
        self._members = np.split(order, starts[1:])
        grouped, r = cells.index[order], cells.resolution
        self.lo = np.minimum.reduceat(grouped, starts, axis=0) * r
        self.hi = (np.maximum.reduceat(grouped, starts, axis=0) + 1) * r
        self._objects: list[fcl.CollisionObject | None] = [None] * len(self._members)
        self.built = 0
        self._creq = fcl.CollisionRequest()
        self._dreq = fcl.DistanceRequest()

    def __len__(self) -> int:
        return len(self._members)

    def _tile(self, t: int) -> fcl.CollisionObject:
        obj = self._objects[t]
        if obj is None:
            vertices, faces = exposed_faces(self.cells, self._members[t])
            obj = self._objects[t] = fcl.CollisionObject(surface_bvh(vertices, faces),
                                                         fcl.Transform())
            self.built += 1
        return obj

    def gaps(self, center: np.ndarray, axes: np.ndarray, half: np.ndarray) -> np.ndarray:
        """[m] a lower bound on the distance from the box ``center``, ``axes`` (columns),
        ``half`` (world; shape (3,), (3, 3), (3,)) to each tile's box, shape (t,): the
        larger of the gap between the two boxes' world-aligned extents and their
        separation along each of the box's own axes (a long link turned diagonally has a
        world extent far larger than itself); 0 where neither separates them."""
        reach = np.abs(axes) @ half  # the box's half extent along the world's axes
        g = np.maximum(np.maximum(self.lo - (center + reach), (center - reach) - self.hi), 0.0)
        out = np.sqrt((g * g).sum(axis=1))
        mid, ext = (self.lo + self.hi) / 2, (self.hi - self.lo) / 2
        along = np.abs((mid - center) @ axes) - ext @ np.abs(axes) - half
        return np.maximum(out, along.max(axis=1, initial=0.0))

    def collide(self, obj: fcl.CollisionObject, center: np.ndarray, axes: np.ndarray,
                half: np.ndarray) -> bool:
        """Whether ``obj`` (placed, inside the box ``center``, ``axes``, ``half``:
        :meth:`gaps`) touches the boundary."""
        for t in np.flatnonzero(self.gaps(center, axes, half) <= 0.0):
            if fcl.collide(obj, self._tile(int(t)), self._creq, fcl.CollisionResult()) > 0:
                return True
        return False

    def within(self, obj: fcl.CollisionObject, center: np.ndarray, axes: np.ndarray,
               half: np.ndarray, reach: float) -> bool:
        """Whether ``obj`` (placed, inside the box ``center``, ``axes``, ``half``) comes
        nearer than ``reach`` [m] to the boundary: only the tiles whose box is nearer
        are asked (a padded world's check of a large base against a table: a few
        tiles, where its exact distance would ask every tile nearer than that)."""
        gaps = self.gaps(center, axes, half)
        for t in np.argsort(gaps, kind="stable"):
            if gaps[t] >= reach:
                break
            d = fcl.distance(obj, self._tile(int(t)), self._dreq, fcl.DistanceResult())
            if max(float(d), 0.0) < reach:
                return True
        return False

    def distance(self, obj: fcl.CollisionObject, center: np.ndarray, axes: np.ndarray,
                 half: np.ndarray) -> float:
        """[m] the distance from ``obj`` (placed, inside the box ``center``, ``axes``,
        ``half``: :meth:`gaps`) to the boundary, 0 where they touch."""
        gaps = self.gaps(center, axes, half)
        best = np.inf
        for t in np.argsort(gaps, kind="stable"):
            if gaps[t] >= best:
                break
            d = fcl.distance(obj, self._tile(int(t)), self._dreq, fcl.DistanceResult())
            best = min(best, max(float(d), 0.0))
            if best <= 0.0:
                break
        return float(best)


def cell_geometry(cells: Cells) -> tuple[CloudSurface, ObbTree, Hull]:
    """The cloud body's FCL geometry (its boundary in tiles, each built on first use),
    OBB tree and hull (:mod:`.cloud_body`)."""
    return CloudSurface(cells), cell_tree(cells), cell_hull(cells)
