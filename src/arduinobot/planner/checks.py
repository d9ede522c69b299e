"""The request checks every layer shares, written once: joint names, position limits
(one tolerance), and the joint step between collision-checked states.

The service's wire requests (:mod:`arduinobot.service.plan.requests`), the motion pipeline
(:mod:`arduinobot.planner.planning.pipeline`), goals (:mod:`arduinobot.planner.planning.goals`) and IK
(:mod:`arduinobot.planner.kinematics.ik`) all call these, so the same value is refused alike
everywhere, with the same field.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from arduinobot.contract.errors import InvalidRequest, JointLimitViolation
from arduinobot.description import Description

#: slack on position limits for values that went through a float round trip (JSON,
#: degrees, a sum of joint steps) [rad]
LIMIT_TOL: float = 1e-9

#: the largest joint motion between two states whose collisions are checked one by one
#: (the verifier's dense states, a blend's sampled check) [rad]
CHECK_STEP: float = 0.002


def check_joint_names(description: Description, names: Iterable[str], *,
                      field: str) -> None:
    """Every name must be an actuated joint of ``description``.

    Raises:
        InvalidRequest: a mimic joint (naming its leader), a fixed joint, or not a joint
            at all (naming the actuated ones); ``field`` is ``<field>.<name>``.
    """
    robot = description.robot
    actuated = robot.actuated_joints
    for name in names:
        if name in actuated:
            continue
        j = robot.joints.get(name) if isinstance(name, str) else None
        if j is not None and j.mimic is not None:
            raise InvalidRequest(
                f"{name} is a mimic joint ({j.mimic.multiplier:g} * {j.mimic.joint} "
                f"+ {j.mimic.offset:g}): command its leader {j.mimic.joint} instead",
                field=f"{field}.{name}", details={"joint": name, "leader": j.mimic.joint})
        what = f"a {j.type} joint" if j is not None else "not a joint of this robot"
        raise InvalidRequest(f"{name} is {what}; actuated joints: {', '.join(actuated)}",
                             field=f"{field}.{name}",
                             details={"joint": name, "actuated": list(actuated)})


def check_positions(names: Sequence[str], values: Iterable[float], limits: np.ndarray, *,
                    field: str) -> None:
    """Each value [rad] within its joint's ``limits`` row (lower, upper), give or take
    :data:`LIMIT_TOL`.

    Raises:
        JointLimitViolation: the first value outside, with field ``<field>.<name>``.
    """
    for name, v, (lo, hi) in zip(names, values, limits):
        if not lo - LIMIT_TOL <= v <= hi + LIMIT_TOL:
            raise JointLimitViolation(name, float(v), float(lo), float(hi),
                                      field=f"{field}.{name}")


def joint_values(description: Description, values: Mapping[str, float] | None, *,
                 field: str) -> dict[str, float]:
    """Check a ``{joint: value}`` map: actuated joints only, within position limits.

    Args:
        values: joint values [rad]; ``None`` is an empty map.
        field: the request field named in errors (``start``, ``goal.joints``).

    Returns:
        Every actuated joint's value in actuated-joint order, 0 for a joint missing from
        ``values``.

    Raises:
        InvalidRequest: an unknown joint, a fixed joint, or a mimic joint (naming its leader).
        JointLimitViolation: a value outside the joint's position limits.
    """
    actuated = description.robot.actuated_joints
    values = dict(values or {})
    check_joint_names(description, values, field=field)
    names = [n for n in actuated if n in values]
    check_positions(names, [float(values[n]) for n in names],
                    description.robot.position_limits(tuple(names)), field=field)
    return {n: float(values.get(n, 0.0)) for n in actuated}
