"""The replies about the served robot itself: its limits and its description.

Answered by the server at once (``<p>/description``) and used by ``--local`` commands
(:mod:`arduinobot.service.local`); imports neither Zenoh nor the server.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

_KINDS = ("lower", "upper", "velocity", "acceleration", "jerk", "effort")


def limits_body(desc: Any, lim: Any = None) -> dict[str, dict[str, float | None]]:
    """Per actuated joint: lower, upper [rad], velocity, acceleration, jerk, effort, as
    the planner enforces them at full scaling (None for an infinite figure). ``lim``: the
    :class:`~arduinobot.planner.kinematics.limits.JointLimits` of ``desc`` if already built."""
    if lim is None:
        from arduinobot.planner.kinematics.limits import JointLimits
        lim = JointLimits.from_description(desc)

    def fin(v: float) -> float | None:
        return float(v) if np.isfinite(v) else None
    return {n: {k: fin(getattr(lim, k)[i]) for k in _KINDS}
            for i, n in enumerate(lim.joint_names)}


def limit_sources_body(lim: Any) -> dict[str, dict[str, str]]:
    """Per actuated joint and limit kind, where the full-scale figure came from: ``urdf``,
    ``config/joint_limits.yaml`` or ``derived: <rule>`` (the planner's defaults), as
    :attr:`~arduinobot.planner.kinematics.limits.JointLimits.sources` records it."""
    return {n: {k: str(lim.sources.get(f"{n}.{k}", "unknown")) for k in _KINDS}
            for n in lim.joint_names}


def description_body(desc: Any) -> dict[str, Any]:
    """The ``<p>/description`` reply: expanded URDF, SRDF text, limits (full scale, with
    where each came from, and the default scaling a request without one gets), joints,
    tcp, and for the shipped model a note on its size (``size_note``, else null)."""
    from arduinobot.planner.kinematics.limits import JointLimits
    robot = desc.robot
    lim = JointLimits.from_description(desc)
    srdf_text = None
    if desc.srdf is not None and desc.srdf.source is not None:
        srdf_text = Path(desc.srdf.source).read_text("utf-8")
    lims = robot.position_limits(robot.actuated_joints)
    return {
        "robot": robot.name,
        "urdf": robot.urdf,
        "srdf": srdf_text,
        "mimic_joints": {n: {"leader": robot.joints[n].mimic.joint,
                             "multiplier": robot.joints[n].mimic.multiplier,
                             "offset": robot.joints[n].mimic.offset}
                         for n in robot.mimic_joints},
        "position_limits": {n: [float(lo), float(hi)]
                            for n, (lo, hi) in zip(robot.actuated_joints, lims)},
        "joint_limits": {k: dict(v) for k, v in desc.joint_limits.items()},
        "limits": limits_body(desc, lim),
        "limit_sources": limit_sources_body(lim),
        **desc.summary(),
        "tcp": None if desc.tcp is None else {"parent_link": desc.tcp.parent_link,
                                              "xyz": list(desc.tcp.xyz),
                                              "source": desc.tcp.source},
        "config": desc.config.to_json(),
        "default_scaling": {"velocity": desc.default_velocity_scaling,
                            "acceleration": desc.default_acceleration_scaling},
        "size_note": desc.size_note,
        "warnings": list(desc.warnings),
    }
