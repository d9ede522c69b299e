"""A checked cloud object made ready to plan against: posed, self-filtered, its unknown
space stated, as one or two cell bodies of a world.

The robot's state at the moment the cloud was taken places the cloud's frame (a link),
the camera (a link) and the robot itself for the self-filter; cells inside the scene's
objects and the objects the robot carries (posed at that state) are removed too. With
``unknown: "occupied"`` the camera's shadow (:mod:`arduinobot.scene.cloud_unknown`) is a
second body ``<id>.unknown`` on its own grid, filtered the same way and also by the
links' convex hulls (the shadow reaches into the robot the camera sees).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.model import Origin
from arduinobot.description.model import rpy_of as rpy_of_matrix
from arduinobot.planner.collision.cloud_body import near_robot, surface_spacing
from arduinobot.scene.cloud import CloudObstacle, UnknownSpace, posed
from arduinobot.scene.cloud_filter import CloudCounts, inside_objects, kept_cells
from arduinobot.scene.cloud_spec import CloudSpec, Placement
from arduinobot.scene.cloud_unknown import Camera, shadow_cells
from arduinobot.scene.obstacles import Obstacle


@dataclass(frozen=True)
class KeptCloud:
    """A cloud ready for a world's ``clouds``.

    Attributes:
        bodies: the measured cells, and the shadow (``<id>.unknown``) when unknown space
            is occupied.
        counts: what became of the points (for the apply reply).
        unknown: the assumption about unseen space.
        shadow: the shadow's cells (0 with ``unknown: "free"``).
    """

    bodies: tuple[CloudObstacle, ...]
    counts: CloudCounts
    unknown: UnknownSpace
    shadow: int

    def reply(self) -> dict[str, object]:
        """The apply reply's entry for this cloud."""
        return {**self.counts.to_mapping(), "unknown": self.unknown, "shadow_cells": self.shadow}


def _pose(at: Placement, link_poses: np.ndarray, link_index: dict[str, int]) -> np.ndarray:
    offset = Origin(xyz=at.xyz, rpy=at.rpy).matrix()
    if at.frame == "world":
        return offset
    return np.asarray(link_poses[link_index[at.frame]] @ offset)


def _carried_in_world(world: object, link_poses: np.ndarray) -> list[Obstacle]:
    out = []
    for a in world.attached:  # type: ignore[attr-defined]
        pose = link_poses[world.kin.link_index[a.link]] @ a.shape.pose()  # type: ignore[attr-defined]
        o = a.shape
        out.append(Obstacle(o.id, o.geometry, xyz=tuple(pose[:3, 3]),
                            rpy=rpy_of_matrix(pose[:3, :3])))
    return out


def _inside_link_hulls(world: object, centers: np.ndarray, link_poses: np.ndarray,
                       padding: float) -> np.ndarray:
    from scipy.spatial import ConvexHull, QhullError

    bodies = world.bodies  # type: ignore[attr-defined]
    out = np.zeros(len(centers), bool)
    for frame, hull in zip(bodies.frames, bodies.hulls):
        t = link_poses[frame]
        local = (centers - t[:3, 3]) @ t[:3, :3]
        # only the centres in the hull's box are tested against its facets (a link is
        # small beside a shadow: a (cells x facets) product would be gigabytes)
        grow = padding + hull.radius
        lo, hi = hull.vertices.min(axis=0) - grow, hull.vertices.max(axis=0) + grow
        near = np.flatnonzero(((local >= lo) & (local <= hi)).all(axis=1))
        if not len(near):
            continue
        try:
            eq = ConvexHull(hull.vertices).equations
        except QhullError:
            out[near] = True  # a flat link: its box stands in
            continue
        for chunk in np.array_split(near, max(1, len(near) * len(eq) // 4_000_000)):
            out[chunk] |= (local[chunk] @ eq[:, :3].T + eq[:, 3] <= grow).all(axis=1)
    return out


def keep_cloud(world: object, spec: CloudSpec, state: np.ndarray, *,
               objects: Sequence[Obstacle] = ()) -> KeptCloud:
    """``spec``'s cells in ``world``'s robot at ``state`` (shape (dof,) [rad]): its
    points posed, less the robot's and the ``objects``' and carried objects' cells.

    Raises:
        InvalidRequest: no cell is left, or the shadow's frustum is too large
            (``<where>.camera.range``); the spec's own refusals came when it was built.
    """
    kin = world.kin  # type: ignore[attr-defined]
    link_poses = kin.link_poses(np.asarray(state, float))
    index = dict(kin.link_index)
    pose = _pose(spec.at, link_poses, index)
    # a cloud in the world's frame as sent (the usual case) is not copied
    pts = spec.points.points if np.array_equal(pose, np.eye(4)) \
        else posed(spec.points.points, pose)
    spacing = surface_spacing(spec.resolution)
    known = [*objects, *_carried_in_world(world, link_poses)]
    cells, counts = kept_cells(
        pts, spec.resolution, dropped=spec.points.dropped, surface_spacing=spacing,
        objects=known, padding=spec.padding, field=f"{spec.where}.points",
        near=lambda c, reach: near_robot(world, state, c, reach, spacing=spacing))
    bodies = [CloudObstacle(spec.id, cells, spec.unknown)] if len(cells) else []
    shadow = 0
    if spec.unknown == "occupied":
        assert spec.camera is not None and spec.camera_at is not None  # CloudSpec checks
        camera = Camera.from_mapping(spec.camera, _pose(spec.camera_at, link_poses, index),
                                     where=f"{spec.where}.camera")
        dark = shadow_cells(pts, camera, spec.resolution, where=f"{spec.where}.camera")
        dark_spacing = surface_spacing(dark.resolution)
        gone = near_robot(world, state, dark, spec.padding + dark_spacing,
                          spacing=dark_spacing)
        gone |= _inside_link_hulls(world, dark.centers, link_poses, spec.padding)
        gone |= inside_objects(dark, known, spec.padding)
        dark = dark.keep(~gone)
        shadow = len(dark)
        if shadow:
            bodies.append(CloudObstacle(f"{spec.id}.unknown", dark, "occupied"))
    if not bodies:
        raise InvalidRequest(f"no cell is left of {counts.points} points (dropped "
                             f"{counts.dropped}, robot {counts.robot}, objects "
                             f"{counts.objects})", field=f"{spec.where}.points",
                             details=counts.to_mapping())
    return KeptCloud(tuple(bodies), counts, spec.unknown, shadow)
