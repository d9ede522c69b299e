"""Attach and detach, once, for the kept scene and for tasks: what they need of the robot
(:class:`Frames`: a state's link poses and a carried object's contacts with the robot)
and the one contact rule.

The scene does not compute frames itself (that is the planner's kinematics and collision
world, a floor up): :class:`arduinobot.planner.frames.RobotFrames` does in its process,
:class:`arduinobot.service.scene.carry.PooledFrames` asks a worker of the service's pool.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import replace
from typing import Any, Protocol

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.cloud import CloudObstacle
from arduinobot.scene.obstacles import AttachedObject, Obstacle, resolve_attached
from arduinobot.scene.pose import rpy_of

_log = logging.getLogger(__name__)


class Frames(Protocol):
    """What attach and detach ask of the robot. A state ``q`` is what :meth:`state`
    returns (opaque to the scene)."""

    description: Any

    def state(self, values: Any, *, field: str) -> Any:
        """``{joint: value}`` (None: all 0), checked (errors name ``field``)."""
        ...

    def link_pose(self, q: Any, link: str) -> np.ndarray:
        """``link``'s pose in the world frame at ``q``, shape (4, 4)."""
        ...

    def link_contacts(self, a: AttachedObject, q: Any) -> list[tuple[str, str]]:
        """The pairs (``a.id``, link) of ``a`` at ``q`` with links not among its touch
        links, sorted."""
        ...

    def keep_cloud(self, data: dict[str, Any], q: Any, *, where: str,
                   objects: Sequence[Obstacle], attached: Sequence[AttachedObject]
                   ) -> tuple[tuple[CloudObstacle, ...], dict[str, Any]]:
        """A ``points`` object (its wire form) kept at ``q``: its cell bodies and its
        counts (:meth:`arduinobot.planner.collision.cloud_keep.KeptCloud.reply`), less
        the robot's cells and the ``objects``' (world) and ``attached`` ones'.

        Raises:
            InvalidRequest: the cloud's refusals, naming the field under ``where``.
        """
        ...


class Grasps(Frames, Protocol):
    """Frames that also tell how far a carried object is from what holds it (a task's
    attach: :class:`arduinobot.planner.frames.RobotFrames`)."""

    def grasp_distance(self, a: AttachedObject, q: Any) -> tuple[float, str]:
        """[m] from ``a`` at ``q`` to the nearest of its link, its touch links and the
        tool point, and which that is."""
        ...


#: [m] the farthest a task's attach takes an object from its link, its touch links and
#: the tool point: farther, the gripper closed on air (a pick's tool point a few cm off
#: is a plan that missed the object, not a grasp)
MAX_GRASP_DISTANCE = 0.03


def pose_of(m: np.ndarray) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """A pose (4, 4) as ``xyz`` [m] and URDF ``rpy`` [rad]."""
    x, y, z = (float(v) for v in m[:3, 3])
    return (x, y, z), rpy_of(m[:3, :3])


def hold(frames: Frames, shape: Obstacle, link: str, q: Any, *,
         touch_links: tuple[str, ...] = (), mass: float = 0.0,
         com: tuple[float, float, float] | None = None, where: str = "attached",
         check: bool = True) -> AttachedObject:
    """``shape`` (posed in ``link``'s frame) carried by ``link``, with its default touch
    links if it names none; with ``check``, refused if at ``q`` it already touches a link
    of the robot that is not a touch link (the one contact rule: an object picked up
    into the arm would be in collision from its first state on).

    Raises:
        InvalidRequest: an unknown link or touch link; a contact (``details.pairs``, at
            field ``where``).
    """
    a = resolve_attached(frames.description, (AttachedObject(
        shape, link, tuple(touch_links), mass, com, where=where),))[0]
    if check:
        pairs = frames.link_contacts(a, q)
        if pairs:
            raise InvalidRequest(
                f"'{a.id}' already touches {', '.join(sorted({b for _, b in pairs}))} of "
                f"the robot, not among its touch links {list(a.touch_links)}: "
                "move the arm, or name the link in touch_links", field=where,
                details={"pairs": [list(p) for p in pairs]})
    return a


def attach(frames: Grasps, obstacle: Obstacle, link: str, q: Any, *,
           touch_links: tuple[str, ...] = (), mass: float = 0.0,
           where: str = "attached", reach: float = MAX_GRASP_DISTANCE) -> AttachedObject:
    """``obstacle`` (posed in the world) taken into ``link``'s frame where it is at
    ``q``, and held (:func:`hold`, contacts checked), within ``reach`` [m] of what
    holds it (a task's pick).

    Raises:
        InvalidRequest: :func:`hold`'s; the object farther than ``reach``
            (``details``: object, distance [m], nearest, max_distance).
    """
    xyz, rpy = pose_of(np.linalg.inv(frames.link_pose(q, link)) @ obstacle.pose())
    a = hold(frames, replace(obstacle, xyz=xyz, rpy=rpy, where=f"{where}.object"), link,
             q, touch_links=touch_links, mass=mass, where=where)
    distance, nearest = frames.grasp_distance(a, q)
    if distance > reach:
        raise InvalidRequest(
            f"'{a.id}' is {distance:.3f} m from {nearest}, the nearest of what would hold "
            f"it ('{a.link}', its touch links, the tool point; at most {reach:.3f} m): "
            "move the arm to the object before attaching it (or give the step a larger "
            "'reach')", field=where,
            details={"object": a.id, "distance": round(distance, 4), "nearest": nearest,
                     "link": a.link, "max_distance": reach})
    return a


def detach(frames: Frames, carried: AttachedObject, q: Any, *,
           where: str = "obstacle") -> Obstacle:
    """``carried`` put down in the world where its link holds it at ``q``."""
    xyz, rpy = pose_of(frames.link_pose(q, carried.link) @ carried.shape.pose())
    return replace(carried.shape, xyz=xyz, rpy=rpy, where=where)


def warn_if_far(frames: Frames, a: AttachedObject, q: Any, *, where: str) -> None:
    """A WARNING when the kept scene's attach takes ``a`` farther than
    :data:`MAX_GRASP_DISTANCE` from what holds it. Not refused there, unlike a task's:
    its state may be a guess (all joints 0 without a robot or a ``state``), and it
    takes an object given in the link's frame where the owner put it (a tool beyond the
    gripper)."""
    grasp = getattr(frames, "grasp_distance", None)
    if grasp is None:
        return
    distance, nearest = grasp(a, q)
    if distance > MAX_GRASP_DISTANCE:
        _log.warning("%s: '%s' is attached %.3f m from %s, the nearest of what holds it "
                     "('%s', its touch links, the tool point): carried from there, though "
                     "no gripper closes on it", where, a.id, distance, nearest, a.link)
