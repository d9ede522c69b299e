"""Scenes the planner tests share: a goal that is free but that no motion reaches.

The arduinobot's base joint (joint_1) turns only within [-pi/2, pi/2], so an arm going
from joint_1 = 1.2 to joint_1 = -1.2 must pass joint_1 = 0, where the whole arm lies in
the vertical plane x = -0.02 (the upper arm's offset). :data:`SPLIT` is a thin wall in
that plane with a window round the shoulder (|y| < 0.62 m, z < 1.12 m) too small for the
0.8 m upper arm in any of its poses, and the base fits through it. Start and goal lean
away from the wall (nothing touches it), yet every state with joint_1 = 0 collides: a
real NO_PATH_FOUND, not a start or goal in collision. Leaning away, the gripper reaches
under the plane the base stands on: plan these with the ground off (``ground=False``,
``"ground": false``; :mod:`arduinobot.scene.ground`), as a wall-mounted arm would.

:data:`SLOT` is the same wall with the window just wide and tall enough for the arm in
a narrow band of poses: a narrow passage, the only way from start to goal.
"""

from __future__ import annotations

from arduinobot.scene.obstacles import Obstacle

_X, _T, _Y, _Z = -0.02, 0.04, 0.62, 1.12  # the plane, the wall's thickness, the window


def split_wall(half_width: float, height: float) -> tuple[Obstacle, ...]:
    """The wall in the plane x = -0.02 with a window |y| < ``half_width`` [m], z <
    ``height`` [m] (2 m wide each side, its roof 2 m tall: past the arm's reach)."""
    y, z = half_width, height
    return (Obstacle("roof", "box", size=(_T, 4.0, 2.0), xyz=(_X, 0.0, z + 1.0)),
            Obstacle("front", "box", size=(_T, 2.0 - y, z), xyz=(_X, (2.0 + y) / 2, z / 2)),
            Obstacle("back", "box", size=(_T, 2.0 - y, z), xyz=(_X, -(2.0 + y) / 2, z / 2)))


SPLIT: tuple[Obstacle, ...] = split_wall(_Y, _Z)
# the window widened just enough for the arm in a narrow band of poses: the upper arm
# leaning far to one side (joint_2 about -1.2 to -1.55 rad) with the forearm bent back
# (joint_3 about -0.5 to 0), 0.9-0.92 m wide and 1.3-1.36 m tall at joint_1 = 0
# (tests/planner/planning/test_narrow_passage.py)
SLOT: tuple[Obstacle, ...] = split_wall(0.92, 1.36)
SPLIT_START = {"joint_1": 1.2, "joint_2": -0.6, "joint_3": -0.6, "joint_4": 0.0}
SPLIT_GOAL = {"joint_1": -1.2, "joint_2": -0.6, "joint_3": -0.6}


def split_dicts() -> list[dict]:
    """:data:`SPLIT` as a plan request's ``obstacles``."""
    return [{"id": o.id, "shape": "box", "size": list(o.size), "xyz": list(o.xyz)}
            for o in SPLIT]
