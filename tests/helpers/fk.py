"""An independent forward kinematics of the tool frame, for tests: scipy rotations over
the model's joint origins and axes (mimics followed), not the planner's numba kernel."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def link_pose(robot, link: str, names, q) -> np.ndarray:
    """``link``'s world pose, shape (4, 4), at joint values ``q`` (ordered as ``names``),
    by walking the URDF joints with scipy (independent of arduinobot.planner.kinematics)."""
    col = {n: i for i, n in enumerate(names)}
    t = np.eye(4)
    for j in robot.link_path(link):
        o = np.eye(4)
        o[:3, :3] = Rotation.from_euler("xyz", j.origin.rpy).as_matrix()
        o[:3, 3] = j.origin.xyz
        t = t @ o
        if j.movable:
            leader, mult, off = (j.mimic.joint, j.mimic.multiplier, j.mimic.offset) \
                if j.mimic else (j.name, 1.0, 0.0)
            v = mult * q[col[leader]] + off
            axis = np.asarray(j.axis, float) / np.linalg.norm(j.axis)
            m = np.eye(4)
            if j.type == "prismatic":
                m[:3, 3] = axis * v
            else:
                m[:3, :3] = Rotation.from_rotvec(axis * v).as_matrix()
            t = t @ m
    return t


def tool_frames(description, names, positions):
    """tcp positions (m, 3) and tool rotations (m, 3, 3), by walking the URDF joints with
    scipy (independent of arduinobot.planner.kinematics)."""
    robot, tcp = description.robot, description.tcp
    ps, rs = [], []
    for q in positions:
        t = link_pose(robot, tcp.parent_link, names, q)
        ps.append(t[:3, :3] @ np.asarray(tcp.xyz, float) + t[:3, 3])
        rs.append(t[:3, :3])
    return np.array(ps), np.array(rs)
