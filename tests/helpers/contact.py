"""An independent check of robot states against obstacles, for tests: each link's
collision meshes loaded by trimesh into python-fcl, placed by tests/helpers/fk.py's scipy
forward kinematics; none of the planner's collision code (worlds, trees, the certifier).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import fcl
import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from tests.helpers.fk import link_pose


class LinkMeshes:
    """The robot's links as FCL meshes (scaled and placed as the URDF says)."""

    def __init__(self, description: Any) -> None:
        self.robot = description.robot
        self.links: dict[str, fcl.CollisionObject] = {}
        for link in self.robot.links.values():
            parts_v, parts_f, n = [], [], 0
            for c in link.collisions:
                g = c.geometry
                tm = trimesh.load(str(g.path), force="mesh")
                v = np.asarray(tm.vertices, float) * np.asarray(g.scale, float)
                o = np.eye(4)
                o[:3, :3] = Rotation.from_euler("xyz", c.origin.rpy).as_matrix()
                o[:3, 3] = c.origin.xyz
                parts_v.append(v @ o[:3, :3].T + o[:3, 3])
                parts_f.append(np.asarray(tm.faces) + n)
                n += len(v)
            if not parts_v:
                continue
            bvh = fcl.BVHModel()
            v, f = np.vstack(parts_v), np.vstack(parts_f)
            bvh.beginModel(len(v), len(f))
            bvh.addSubModel(v, f)
            bvh.endModel()
            self.links[link.name] = fcl.CollisionObject(bvh, fcl.Transform())

    def contacts(self, names: Sequence[str], states: np.ndarray,
                 obstacle: Mapping[str, Any]) -> list[tuple[int, str]]:
        """(state index, link) of every link touching ``obstacle`` (a sphere or box in
        the plan request's form) at each of ``states`` ((m, len(names)) [rad])."""
        xyz = np.asarray(obstacle.get("xyz", (0, 0, 0)), float)
        rot = Rotation.from_euler("xyz", obstacle.get("rpy", (0, 0, 0))).as_matrix()
        if obstacle["shape"] == "sphere":
            geom = fcl.Sphere(float(obstacle["radius"]))
        else:
            geom = fcl.Box(*map(float, obstacle["size"]))
        ob = fcl.CollisionObject(geom, fcl.Transform(rot, xyz))
        hits = []
        for k, q in enumerate(np.atleast_2d(states)):
            for name, obj in self.links.items():
                t = link_pose(self.robot, name, names, q)
                obj.setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
                if fcl.collide(obj, ob, fcl.CollisionRequest(), fcl.CollisionResult()) > 0:
                    hits.append((k, name))
        return hits
