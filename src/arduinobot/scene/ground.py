"""The ground: the plane the robot's base stands on, an obstacle unless a request opts out.

The plane is z = 0 of the robot's root frame (the base's parent, where every obstacle is
posed). For planning it is a large thin box whose top face is that plane; links that never
move (the base, on or under the plane) are allowed to touch it. The MuJoCo twin gets the
same plane as a floor, so a released object lands on it instead of falling for ever.
"""

from __future__ import annotations

from arduinobot.scene.obstacles import Obstacle

#: The ground's obstacle id (reserved: a request's own obstacle of that id replaces it).
GROUND_ID = "ground"
#: Edge length [m] of the ground box: far beyond any arm's reach.
GROUND_SIDE = 20.0
#: Thickness [m] of the ground box: thicker than a motion's step between checked states,
#: so no sampled motion can pass through it unnoticed.
GROUND_THICKNESS = 0.2


def ground_obstacle() -> Obstacle:
    """The ground as a box obstacle whose top face is z = 0 of the root frame."""
    return Obstacle(GROUND_ID, "box", size=(GROUND_SIDE, GROUND_SIDE, GROUND_THICKNESS),
                    xyz=(0.0, 0.0, -GROUND_THICKNESS / 2), where="ground")


def with_ground(obstacles: tuple[Obstacle, ...], ground: bool = True
                ) -> tuple[Obstacle, ...]:
    """``obstacles`` and the ground after them, unless ``ground`` is false or one of them
    has the ground's id already (a user's own ground replaces ours)."""
    if not ground or any(o.id == GROUND_ID for o in obstacles):
        return obstacles
    return (*obstacles, ground_obstacle())
