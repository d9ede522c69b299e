"""Where a camera is: its link's pose from the model's forward kinematics at a state, and
the optical frame OpenCV measures in (z along the view, x right, y down in the image).

A camera link's optical axis is its +x (the URDF/Gazebo convention: x forward, y left,
z up), unless the link is, or has on a fixed joint, a ROS optical frame (a link named
``*_optical*``), whose +z is the optical axis.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.planner.kinematics.chain import Kinematics

log = logging.getLogger(__name__)

#: the optical frame in a URDF/Gazebo camera link's frame: optical z = link x,
#: optical x = -link y, optical y = -link z
LINK_TO_OPTICAL = np.array([[0.0, 0.0, 1.0, 0.0],
                            [-1.0, 0.0, 0.0, 0.0],
                            [0.0, -1.0, 0.0, 0.0],
                            [0.0, 0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CameraFrame:
    """A camera's optical frame in the world.

    Attributes:
        link: the link named; frame: the link whose pose is used (the optical child if
            the link has one); optical: whether ``frame`` is a ROS optical frame (+z).
        pose: world -> optical frame, shape (4, 4).
    """

    link: str
    frame: str
    optical: bool
    pose: np.ndarray


def _is_optical(name: str) -> bool:
    return "_optical" in name


def default_camera(description: Description, sensor_links: tuple[str, ...] = ()) -> str:
    """The camera of a request that names none: the first Gazebo camera sensor's link,
    else the one link named ``*camera*``."""
    if sensor_links:
        return sensor_links[0]
    links = [n for n in description.robot.links if "camera" in n and not _is_optical(n)]
    if len(links) == 1:
        return links[0]
    raise InvalidRequest("the model has " + ("no camera link" if not links else
                         f"several camera links ({', '.join(links)})")
                         + "; name one", field="camera")


def optical_frame_of(description: Description, link: str) -> tuple[str, bool]:
    """The frame to measure in for camera ``link``: itself if it is an optical frame, a
    fixed child named ``*_optical*`` if it has one, else itself (+x forward)."""
    robot = description.robot
    if link not in robot.links:
        raise InvalidRequest(f"{link!r} is not a link of the model (camera links: "
                             f"{', '.join(n for n in robot.links if 'camera' in n) or 'none'})",
                             field="camera")
    if _is_optical(link):
        return link, True
    for j in robot.child_joints.get(link, ()):
        if j.type == "fixed" and _is_optical(j.child):
            return j.child, True
    return link, False


def camera_frame(description: Description, link: str,
                 state: Mapping[str, float] | None = None) -> CameraFrame:
    """The optical frame of camera ``link`` at ``state`` (joint name -> [rad] or [m];
    joints not named are at the model's initial positions, else 0)."""
    frame, optical = optical_frame_of(description, link)
    kin = Kinematics(description.robot)
    q = np.array([description.initial_positions.get(j, 0.0) for j in kin.joint_names],
                 dtype=np.float64)
    for name, value in (state or {}).items():
        if name not in kin.joint_names:
            raise InvalidRequest(f"{name!r} is not a movable joint of the model",
                                 field=f"state.{name}")
        q[kin.joint_names.index(name)] = float(value)
    pose = kin.link_pose(q, frame)
    if not optical:
        pose = pose @ LINK_TO_OPTICAL
    return CameraFrame(link=link, frame=frame, optical=optical, pose=pose)
