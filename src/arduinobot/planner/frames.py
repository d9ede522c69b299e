"""What the scene's attach and detach need of the robot, computed in this process
(:class:`arduinobot.scene.frames.Frames`): a state's link poses and whether a carried
object already touches a link it may not.

Built once, lazily: the kinematics on the first attach or detach, the robot's collision
geometry on the first contact check (a collision world with the carried object alone:
its contacts with the scene are the plans' business, a box picked from a table rests on
it). A worker of the service's pool holds one for the kept scene; a task plans with one
sharing its planner's kinematics and robot bodies.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

from arduinobot.description import Description
from arduinobot.planner.checks import joint_values
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle


class RobotFrames:
    """One robot description's link poses and carried-object contacts.

    Args:
        kin: its :class:`~arduinobot.planner.kinematics.chain.Kinematics` (None: built
            on first use).
        bodies: its robot's collision bodies (None: built on the first contact check).
    """

    def __init__(self, description: Description, *, kin: Any = None,
                 bodies: Any = None) -> None:
        self.description = description
        self._lock = threading.Lock()
        self._kin = kin
        self._bodies = bodies

    def kinematics(self) -> Any:
        """The robot's kinematics (built on the first call)."""
        with self._lock:
            if self._kin is None:
                from arduinobot.planner.kinematics.chain import Kinematics
                self._kin = Kinematics(self.description.robot)
            return self._kin

    def state(self, values: Any, *, field: str) -> np.ndarray:
        """``{joint: value}`` (None: all 0) as positions in the kinematics' joint order.

        Raises:
            InvalidRequest, JointLimitViolation: naming ``field``.
        """
        vals = joint_values(self.description, values, field=field)
        return np.array([vals[n] for n in self.kinematics().joint_names], float)

    def link_pose(self, q: np.ndarray, link: str) -> np.ndarray:
        """``link``'s pose in the world frame at ``q``, shape (4, 4)."""
        kin = self.kinematics()
        return np.asarray(kin.link_poses(q)[kin.link_index[link]], float)

    def link_contacts(self, a: AttachedObject, q: np.ndarray) -> list[tuple[str, str]]:
        """The pairs (``a.id``, link) of ``a`` at ``q`` with robot links that are not its
        touch links."""
        from arduinobot.planner.collision.world import CollisionWorld

        with self._lock:
            world = CollisionWorld(self.description, attached=(a,), bodies=self._bodies)
            self._bodies = world.bodies  # the robot's geometry, built once
        links = set(self.description.robot.links)
        out = []
        for x, y in world.check(q).pairs:
            if a.id in (x, y):
                other = y if x == a.id else x
                if other in links:
                    out.append((a.id, other))
        return sorted(set(out))

    def grasp_distance(self, a: AttachedObject, q: np.ndarray) -> tuple[float, str]:
        """How far [m] ``a`` (held by its link at ``q``) is from what would hold it, and
        from which: the nearest of the tool point (when its link is ``a``'s link or a
        touch link) and the collision geometry of ``a``'s link and its touch links
        (FCL's distance, 0 on contact)."""
        import fcl

        from arduinobot.planner.collision.bodies import RobotBodies, bvh

        kin = self.kinematics()
        with self._lock:
            if self._bodies is None:
                self._bodies = RobotBodies.build(self.description, kin)
            bodies = self._bodies
        poses = kin.link_poses(q)
        g = a.shape.geometry
        geom = g.collision_geometry() if g.half_extents() is not None \
            and g.hull_points() is not None else bvh(g.triangles())
        pose = poses[kin.link_index[a.link]] @ a.shape.pose()
        obj = fcl.CollisionObject(geom, fcl.Transform(pose[:3, :3], pose[:3, 3]))
        holders = (a.link, *a.touch_links)
        found: list[tuple[float, str]] = []
        tcp = self.description.tcp
        if tcp is not None and tcp.parent_link in holders:
            point = poses[kin.link_index[tcp.parent_link]] @ np.array([*tcp.xyz, 1.0])
            dot = fcl.CollisionObject(fcl.Sphere(1e-6), fcl.Transform(point[:3]))
            found.append((self._distance(obj, dot), "the tool point"))
        for name, frame, geo in zip(bodies.names, bodies.frames, bodies.geometries):
            if name in holders:
                t = poses[frame]
                other = fcl.CollisionObject(geo, fcl.Transform(t[:3, :3], t[:3, 3]))
                found.append((self._distance(obj, other), name))
        if not found:  # nothing with geometry holds it: the link's origin
            origin = poses[kin.link_index[a.link]][:3, 3]
            dot = fcl.CollisionObject(fcl.Sphere(1e-6), fcl.Transform(origin))
            found.append((self._distance(obj, dot), a.link))
        return min(found)

    @staticmethod
    def _distance(x: Any, y: Any) -> float:
        import fcl
        d = fcl.distance(x, y, fcl.DistanceRequest(), fcl.DistanceResult())
        return max(float(d), 0.0)  # FCL gives -1 for objects in contact

    def keep_cloud(self, data: dict[str, Any], q: np.ndarray, *, where: str,
                   objects: Sequence[Obstacle], attached: Sequence[AttachedObject]
                   ) -> tuple[tuple[CloudObstacle, ...], dict[str, Any]]:
        """A ``points`` object kept at ``q`` (see :class:`arduinobot.scene.frames.Frames`)."""
        from arduinobot.planner.collision.cloud_keep import keep_cloud
        from arduinobot.planner.collision.world import CollisionWorld
        from arduinobot.scene.cloud_spec import CloudSpec

        spec = CloudSpec.from_mapping(data, link_names=tuple(self.description.robot.links),
                                      where=where)
        with self._lock:
            world = CollisionWorld(self.description, attached=tuple(attached),
                                   bodies=self._bodies)
            self._bodies = world.bodies
        kept = keep_cloud(world, spec, q, objects=tuple(objects))
        return kept.bodies, kept.reply()
