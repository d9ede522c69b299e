"""What a motion reached, against what its goal asked: every reply reports it.

:class:`Reached` is the tool frame at the trajectory's last state (the tcp point with
its parent link's axes) and the residuals to the goal: the tcp's distance from a
position, the rotation vector from a goal orientation (per axis of the goal frame), each
joint's distance from its goal value; ``within_tolerance`` says whether they are within
the goal's tolerances (the exact goal's when it has none: 1e-6 m, 1e-6 rad).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from arduinobot.description import Description
from arduinobot.description.model import rpy_of
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.rotations import (
    matrix_of_quaternion,
    quaternion_of_matrix,
    rotation_error,
)
from arduinobot.planner.planning.goal_states import named_values
from arduinobot.planner.planning.goals import (
    Goal,
    JointGoal,
    LineGoal,
    NamedGoal,
    PoseGoal,
    PositionGoal,
)

__all__ = ["Reached", "reached"]

#: [m or rad] what "exactly" means for a goal without a tolerance (the IK's own)
EXACT = 1e-6


@dataclass(frozen=True)
class Reached:
    """The tool frame at the end and the residuals to the goal (see the module doc).

    Attributes:
        position: tcp [m], shape (3,), or None (a model without a tcp).
        orientation: the tool frame's quaternion (x, y, z, w); ``rpy`` [rad] the same.
        position_error: [m] from the goal's position (position, pose and line goals).
        orientation_error: [rad] rotation vector from the goal's orientation to the
            reached one, components along the goal frame's x, y, z (pose goals).
        joint_errors: [rad] reached minus goal value per joint (joint and named goals).
        within_tolerance: every residual within the goal's tolerance.
    """

    position: tuple[float, float, float] | None
    orientation: tuple[float, float, float, float] | None
    rpy: tuple[float, float, float] | None
    position_error: float | None = None
    orientation_error: tuple[float, float, float] | None = None
    joint_errors: Mapping[str, float] = field(default_factory=dict)
    within_tolerance: bool = True

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"within_tolerance": self.within_tolerance}
        if self.position is not None:
            out["position"] = list(self.position)
            out["orientation"] = list(self.orientation or ())
            out["rpy"] = list(self.rpy or ())
        residuals: dict[str, object] = {}
        if self.position_error is not None:
            residuals["position"] = self.position_error
        if self.orientation_error is not None:
            residuals["orientation"] = list(self.orientation_error)
        if self.joint_errors:
            residuals["joints"] = dict(self.joint_errors)
        out["residuals"] = residuals
        return out


def reached(description: Description, kin: Kinematics, goal: Goal, q: np.ndarray, *,
            group: str, target: np.ndarray | None = None) -> Reached:
    """What the state ``q`` (the trajectory's last, full joint vector) reaches against
    ``goal``. ``target``: a line goal's end point [m] (its offset resolved)."""
    tcp = description.tcp
    pos = ori = rpy = None
    rot = None
    if tcp is not None and tcp.parent_link in kin.link_index:
        t = kin.link_pose(q, tcp.parent_link)
        p = t[:3, :3] @ np.asarray(tcp.xyz, float) + t[:3, 3]
        rot = t[:3, :3] @ tcp.rotation()  # the tool frame's, as goals give it
        pos = tuple(float(v) for v in p)
        ori, rpy = quaternion_of_matrix(rot), rpy_of(rot)
    ok = True
    pos_err = ori_err = None
    joint_err: dict[str, float] = {}
    goal_p = None
    tol = EXACT
    if isinstance(goal, (PositionGoal, PoseGoal)):
        goal_p, tol = np.asarray(goal.position), max(goal.tolerance, EXACT)
    elif isinstance(goal, LineGoal):
        goal_p = target if target is not None else (
            np.asarray(goal.position) if goal.position is not None else None)
    if goal_p is not None and pos is not None:
        pos_err = float(np.linalg.norm(np.asarray(pos) - goal_p))
        ok &= pos_err <= tol
    if isinstance(goal, PoseGoal) and rot is not None:
        e = rotation_error(matrix_of_quaternion(goal.orientation), rot)
        ori_err = tuple(float(v) for v in e)
        ok &= bool(np.all(np.abs(e) <= np.maximum(goal.limits, EXACT)))
    if isinstance(goal, (JointGoal, NamedGoal)):
        idx = {n: i for i, n in enumerate(kin.joint_names)}
        values = goal.values if isinstance(goal, JointGoal) else \
            named_values(description, goal.name, group, idx)
        tols = goal.tolerances if isinstance(goal, JointGoal) else {}
        for name, v in values.items():
            if name in idx:
                d = float(q[idx[name]] - v)
                joint_err[name] = d
                ok &= abs(d) <= max(tols.get(name, 0.0), EXACT)
    return Reached(position=pos, orientation=ori, rpy=rpy, position_error=pos_err,  # type: ignore[arg-type]
                   orientation_error=ori_err, joint_errors=joint_err,  # type: ignore[arg-type]
                   within_tolerance=bool(ok) and all(map(math.isfinite, joint_err.values())))
