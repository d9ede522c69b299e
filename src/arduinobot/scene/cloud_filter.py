"""What a cloud's cells are not: the robot itself, and the objects the scene already has.

A depth camera sees the arm and the objects the scene already holds; kept as cells they
would make every start state collide (the arm) or count an object twice (a box and its
measured surface). Both filters remove cells and say how many measured points those
cells held (:class:`CloudCounts`), for the apply reply.

- :func:`near_surface`: cells that may come within ``padding`` of points sampled on the
  robot's surface at the state the cloud was taken (the planner samples them:
  :mod:`arduinobot.planner.collision.cloud_body`).
- :func:`inside_objects`: cells whose centre lies inside an obstacle or a carried object
  (posed in the world), grown by ``padding``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from arduinobot.scene.cloud import Cells, voxelise
from arduinobot.scene.obstacles import Obstacle

#: [m] the self-filter's default padding: a depth camera's noise at a metre
DEFAULT_PADDING = 0.01


@dataclass(frozen=True)
class CloudCounts:
    """How a cloud's points fared, for the apply reply.

    Attributes:
        points: points received.
        kept: points in the cells kept.
        dropped: points dropped as NaN or infinite.
        robot: points in cells removed as the robot's own.
        objects: points in cells removed as inside a known object.
        cells: the cells kept.
    """

    points: int
    kept: int
    dropped: int
    robot: int
    objects: int
    cells: int

    def to_mapping(self) -> dict[str, int]:
        return {"points": self.points, "kept": self.kept, "dropped": self.dropped,
                "filtered_robot": self.robot, "filtered_objects": self.objects,
                "cells": self.cells}


def near_surface(cells: Cells, surface: np.ndarray, padding: float) -> np.ndarray:
    """Which cells (shape (n,) bool) may come within ``padding`` [m] of the points
    ``surface`` (shape (k, 3) [m], world): those whose centre is within ``padding`` plus
    the cell's half diagonal of one of them (the box may then reach into the padding).

    The surface points must be dense (the planner's are no farther apart than half a
    cell), so a measured point on the robot lies near one of them."""
    if len(cells) == 0 or len(surface) == 0:
        return np.zeros(len(cells), bool)
    reach = padding + cells.resolution * math.sqrt(3) / 2
    centers = cells.centers
    # only the centres within reach of the surface's box can be within reach of it: a
    # table of 100k cells under a small arm asks the tree about a few thousand
    near = np.flatnonzero(((centers >= surface.min(axis=0) - reach)
                           & (centers <= surface.max(axis=0) + reach)).all(axis=1))
    out = np.zeros(len(cells), bool)
    if len(near):
        d, _ = cKDTree(surface).query(centers[near], k=1, distance_upper_bound=reach)
        out[near] = d <= reach
    return out


def inside_objects(cells: Cells, objects: Sequence[Obstacle], padding: float = 0.0
                   ) -> np.ndarray:
    """Which cells (shape (n,) bool) have their centre inside one of ``objects`` (world
    poses) grown by ``padding`` [m]; a mesh object counts as its convex hull."""
    out = np.zeros(len(cells), bool)
    if len(cells) == 0:
        return out
    centers = cells.centers
    for o in objects:
        pose = o.pose()
        local = (centers - pose[:3, 3]) @ pose[:3, :3]
        out |= o.geometry.contains(local, padding)
    return out


def points_in(mask: np.ndarray, inverse: np.ndarray) -> int:
    """How many points lie in the cells ``mask`` marks, ``inverse`` each point's cell."""
    return int(np.count_nonzero(mask[inverse]))


def kept_cells(points: np.ndarray, resolution: float, *, dropped: int = 0,
               surface: np.ndarray | None = None, surface_spacing: float = 0.0,
               objects: Sequence[Obstacle] = (), padding: float = DEFAULT_PADDING,
               field: str = "points",
               near: Callable[[Cells, float], np.ndarray] | None = None
               ) -> tuple[Cells, CloudCounts]:
    """The cells of world points ``points`` (shape (n, 3) [m], finite) less the robot's
    (within ``padding`` [m] of ``surface``, points no farther than ``surface_spacing``
    [m] from every point of the robot's surface) and the ``objects``' (grown by
    ``padding``), and how many points each step took. ``near(cells, reach)``, if given,
    finds the robot's cells instead of ``surface`` (the same cells as
    :func:`near_surface` on it, found without the surface in the world's frame)."""
    cells, inverse = voxelise(points, resolution, field=field)
    if near is not None:
        robot = near(cells, padding + surface_spacing)
    elif surface is not None:
        robot = near_surface(cells, surface, padding + surface_spacing)
    else:
        robot = np.zeros(len(cells), bool)
    inside = inside_objects(cells, objects, padding) & ~robot
    kept = ~(robot | inside)
    counts = CloudCounts(points=len(points) + dropped, kept=points_in(kept, inverse),
                         dropped=dropped, robot=points_in(robot, inverse),
                         objects=points_in(inside, inverse), cells=int(kept.sum()))
    return cells.keep(kept), counts
