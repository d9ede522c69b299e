"""What the kept scene needs of the robot to attach and detach: a state's link poses and
whether a carried object already touches a link it may not.

:class:`RobotFrames` computes them in its process, built once, lazily: the kinematics on
the first attach or detach, the robot's collision geometry on the first attach (the
planner's collision world, with the carried object alone: its contacts with the scene are
the plans' business, a box picked from a table rests on it). A worker of the service's
pool holds one; the serving process holds a :class:`PooledFrames`, which asks the pool
(a ``frames`` job), so it never imports the planner nor holds the GIL for a collision
check next to Zenoh's callbacks.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping
from typing import Any

import numpy as np
import orjson

from arduinobot.contract.errors import PlanningError
from arduinobot.description import Description
from arduinobot.scene.obstacles import AttachedObject, resolve_attached
from arduinobot.service.messages import Failure, Submit, outcome_of
from arduinobot.service.plan.requests import joint_values

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
                from arduinobot.planner.kinematics.chain import Kinematics
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



class PooledFrames(RobotFrames):
    """:class:`RobotFrames` whose link poses and contacts a worker of the pool computes
    (``frames`` jobs, :func:`answer_frames`); a state is checked here (no planner needed).
    A state is the checked ``{joint: value}`` map: the worker orders it."""

    def __init__(self, description: Description, *, submit: Submit) -> None:
        super().__init__(description)
        self._submit = submit

    def state(self, values: Any, *, field: str) -> Any:
        return joint_values(self.description, values, field=field)

    def link_pose(self, q: Any, link: str) -> np.ndarray:
        return np.array(self._ask({"op": "link_pose", "joints": q, "link": link})["pose"],
                        float)

    def link_contacts(self, a: AttachedObject, q: Any) -> list[tuple[str, str]]:
        pairs = self._ask({"op": "contacts", "joints": q, "attached": a})["pairs"]
        return [(x, y) for x, y in pairs]

    def _ask(self, data: Mapping[str, Any]) -> dict[str, Any]:
        out = outcome_of(self._submit, "frames", data)
        if isinstance(out, Failure):
            err = PlanningError(f"the robot's frames could not be computed: {out.message}",
                                details=dict(out.details))
            err.code = out.code
            raise err
        return orjson.loads(out.body)


def answer_frames(frames: RobotFrames, data: Mapping[str, Any]) -> dict[str, Any]:
    """A ``frames`` job in a worker: ``link_pose`` -> ``{"pose": 4x4}``, ``contacts``
    -> ``{"pairs": [[object, link], ...]}``, at the state ``data["joints"]`` (checked by
    :meth:`PooledFrames.state`)."""
    names = frames._kinematics().joint_names
    joints = data["joints"]
    q = np.array([joints[n] for n in names], float)
    if data["op"] == "link_pose":
        return {"pose": frames.link_pose(q, data["link"]).tolist()}
    return {"pairs": [list(p) for p in frames.link_contacts(data["attached"], q)]}
