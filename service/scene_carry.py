"""What the kept scene needs of the robot to attach and detach: a state's link poses and
whether a carried object already touches a link it may not.

Built once per instance, lazily: the kinematics on the first attach or detach, the
robot's collision geometry on the first attach (the planner's collision world, with the
carried object alone: its contacts with the scene are the plans' business, a box picked
from a table rests on it).
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import numpy as np

from description import Description
from planner.scene import AttachedObject, resolve_attached

from .requests import joint_values

_log = logging.getLogger(__name__)


class RobotFrames:
    """One robot description's link poses and carried-object contacts."""

    def __init__(self, description: Description) -> None:
        self.description = description
        self._lock = threading.Lock()
        self._kin: Any = None
        self._bodies: Any = None

    def _kinematics(self) -> Any:
        with self._lock:
            if self._kin is None:
                from planner.kinematics.chain import Kinematics
                self._kin = Kinematics(self.description.robot)
            return self._kin

    def state(self, values: Any, *, field: str) -> np.ndarray:
        """``{joint: value}`` (None: all 0) as positions in the kinematics' joint order.

        Raises:
            InvalidRequest, JointLimitViolation: naming ``field``.
        """
        vals = joint_values(self.description, values, field=field)
        return np.array([vals[n] for n in self._kinematics().joint_names], float)

    def link_pose(self, q: np.ndarray, link: str) -> np.ndarray:
        """``link``'s pose in the world frame at ``q``, shape (4, 4)."""
        kin = self._kinematics()
        return np.asarray(kin.link_poses(q)[kin.link_index[link]], float)

    def resolve(self, a: AttachedObject) -> AttachedObject:
        """``a`` checked against the robot, with its default touch links if it has none."""
        return resolve_attached(self.description, (a,))[0]

    def link_contacts(self, a: AttachedObject, q: np.ndarray) -> list[tuple[str, str]]:
        """The pairs (``a.id``, link) of ``a`` at ``q`` with robot links that are not its
        touch links."""
        from planner.collision.world import CollisionWorld

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
