"""The two-finger claw as a pick sees it (two moving fingers, or one moving jaw against
the link it turns on, as the SO-101's): how far its fingertips open over the gripper's
joint range, where their midpoint is, and the axis they close along, all in the frame of
the link that holds what it picks up, from the finger links' collision meshes.

Nothing here is configured: a claw whose fingers are longer, or open wider, gives its own
numbers (the course's 10x model opens 0.33 m at its tips, the shipped arduinobot too).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.planner.tasks.gripper import gripper_group, holding_link

#: the fraction of a finger's length (along the fingers) that grips: its tip region
TIP_FRACTION = 0.1
#: [m] the tip region is at least this long
MIN_TIP = 0.01
#: leader values sampled over the gripper joint's range
SAMPLES = 61


@dataclass(frozen=True)
class Claw:
    """The claw's geometry in ``link``'s frame (every vector there).

    ``values`` [rad] the leading gripper joint's samples over its range, ``gaps`` [m]
    the fingertips' gap at each (negative: the tips overlap), ``centres`` (n, 3) [m] the
    midpoint between the tips, ``axis`` the unit vector the fingers close along,
    ``along`` the unit vector from the knuckles to the tips.
    """

    link: str
    leader: str
    fingers: tuple[str, str]
    values: np.ndarray
    gaps: np.ndarray
    centres: np.ndarray
    axis: np.ndarray
    along: np.ndarray

    @property
    def opening(self) -> float:
        """[m] the widest the fingertips open over the joint's range."""
        return float(self.gaps.max())

    def value_for(self, width: float) -> float:
        """The leader's value [rad] whose fingertip gap is ``width`` [m] (on the stretch
        from the most closed sample to the widest), clamped to that stretch."""
        lo, hi = int(np.argmin(self.gaps)), int(np.argmax(self.gaps))
        idx = np.arange(min(lo, hi), max(lo, hi) + 1)
        gaps, vals = self.gaps[idx], self.values[idx]
        order = np.argsort(gaps)
        return float(np.interp(width, gaps[order], vals[order]))

    def centre_at(self, value: float) -> np.ndarray:
        """[m] the tips' midpoint at the leader's ``value``, in ``link``'s frame."""
        return np.array([np.interp(value, self.values, self.centres[:, k]) for k in range(3)])


def claw_of(planner: object) -> Claw:
    """The claw of ``planner``'s robot (a :class:`MotionPlanner`).

    Raises:
        InvalidRequest: (field ``pick``) no gripper group, or not two finger links with
            collision meshes under it.
    """
    desc = planner.description  # type: ignore[attr-defined]
    world = planner.world(())  # type: ignore[attr-defined]
    kin = world.kin
    group = gripper_group(desc)
    joints = desc.group_joints().get(group, [])
    if not joints:
        raise InvalidRequest(f"the gripper group '{group}' moves no joint", field="pick")
    leader = joints[0]
    robot = desc.robot
    movers = [leader, *robot.mimics_of(leader), *joints[1:]]
    points = dict(world.bodies.points)
    fingers = list(dict.fromkeys(robot.joints[j].child for j in movers
                                 if robot.joints[j].child in points))
    if len(fingers) == 1:
        # one moving jaw (the SO-101's): the other is the link it turns on, whose far
        # end (along the claw) is the fixed jaw's tip
        fixed = robot.joints[leader].parent
        if fixed in points:
            fingers = [fixed, fingers[0]]
    if len(fingers) != 2:
        raise InvalidRequest(f"a pick needs a claw of two fingers with collision meshes, "
                             f"or one moving jaw against the link it turns on; the "
                             f"gripper group '{group}' moves {len(fingers)} "
                             f"({', '.join(fingers) or 'none'})", field="pick")
    link = holding_link(desc)
    names = list(kin.joint_names)
    lim = planner.limits(1.0, 1.0)  # type: ignore[attr-defined]
    k = names.index(leader)
    values = np.linspace(float(lim.lower[k]), float(lim.upper[k]), SAMPLES)

    def finger_points(v: float, *, origins: bool = False) -> list[np.ndarray]:
        q = np.zeros(len(names))
        q[k] = v
        inv = np.linalg.inv(kin.link_pose(q, link))
        out = []
        for f in fingers:
            t = inv @ kin.link_pose(q, f)
            out.append(t[:3, 3] if origins else points[f] @ t[:3, :3].T + t[:3, 3])
        return out

    # the claw's long axis: the bisector of each finger's own (its vertices' principal
    # axis, pointing from the finger's joint towards its vertices: its tip), at the
    # middle of the range
    mid = float(values[len(values) // 2])
    axes = []
    for p, o in zip(finger_points(mid), finger_points(mid, origins=True)):
        a = np.linalg.svd(p - p.mean(0), full_matrices=False)[2][0]
        axes.append(a if float((p.mean(0) - o) @ a) >= 0 else -a)
    along = (axes[0] + axes[1]) / np.linalg.norm(axes[0] + axes[1])
    widest = finger_points(float(values[0])), finger_points(float(values[-1]))
    spread = [np.linalg.norm(a[0].mean(0) - a[1].mean(0)) for a in widest]
    a0, a1 = widest[int(np.argmax(spread))]
    axis = a1.mean(0) - a0.mean(0)
    axis -= (axis @ along) * along
    axis /= np.linalg.norm(axis)
    gaps, centres = [], []
    for v in values:
        p0, p1 = finger_points(float(v))
        tips = []
        for p in (p0, p1):
            s = p @ along
            length = float(s.max() - s.min())
            tips.append(p[s >= s.max() - max(MIN_TIP, TIP_FRACTION * length)])
        t0, t1 = tips
        gap = float((t1 @ axis).min() - (t0 @ axis).max())
        mid_axis = ((t1 @ axis).min() + (t0 @ axis).max()) / 2
        mean = (t0.mean(0) + t1.mean(0)) / 2
        centres.append(mean + (mid_axis - mean @ axis) * axis)
        gaps.append(gap)
    return Claw(link, leader, (fingers[0], fingers[1]), values, np.array(gaps),
                np.array(centres), axis, along)
