"""Independent FCL objects for a world's bodies (tests check the world against them).

Built from the robot's shared BVHs and the obstacles' own primitives, and placed by the
world's public body table, so a test never reaches into the world's private objects.
"""

from __future__ import annotations

import fcl
import numpy as np

from arduinobot.planner.collision.table import BodyKind
from arduinobot.planner.collision.world import CollisionWorld


def fcl_objects(w: CollisionWorld) -> list[fcl.CollisionObject]:
    """One FCL object per body of ``w``'s table (obstacles placed, links at identity)."""
    objs = [fcl.CollisionObject(g, fcl.Transform()) for g in w.bodies.geometries]
    for o in w.obstacles:
        if o.shape == "box":
            geom = fcl.Box(*o.size)
        elif o.shape == "sphere":
            geom = fcl.Sphere(o.radius)
        else:
            geom = fcl.Cylinder(o.radius, o.length)
        t = o.pose()
        objs.append(fcl.CollisionObject(geom, fcl.Transform(t[:3, :3], t[:3, 3])))
    assert len(objs) == len(w.table)
    assert all(k == BodyKind.OBSTACLE for k in w.table.kinds[len(w.bodies.geometries):])
    return objs


def place(w: CollisionWorld, objs: list[fcl.CollisionObject], poses: np.ndarray,
          *bodies: int) -> None:
    """Move ``bodies``' objects to their poses at link poses ``poses``."""
    for b in bodies:
        t = w.body_pose(poses, b)
        objs[b].setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
