"""A package's YAML config read against the robot: MoveIt's ``joint_limits.yaml``
(per-joint limits, default scaling, position ranges that narrow the URDF's) and
``initial_positions.yaml``. (``tcp.yaml``: :mod:`arduinobot.description.tcp`.)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from arduinobot.description.errors import DescriptionError, InvalidModel
from arduinobot.description.model import Robot


def read_yaml(path: Path) -> object:
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as e:
        raise DescriptionError(f"not valid YAML: {e}", file=path) from e


def read_joint_limits(path: Path, robot: Robot
                       ) -> tuple[dict[str, dict[str, object]], tuple[float, float]]:
    """MoveIt's joint_limits.yaml: per-joint entries, and the default velocity and
    acceleration scaling factors (1 when absent)."""
    data = read_yaml(path)
    if not isinstance(data, dict):
        raise InvalidModel("needs a 'joint_limits' mapping (MoveIt's format)", file=path)
    limits = data.get("joint_limits")
    if not isinstance(limits, dict):
        raise InvalidModel("needs a 'joint_limits' mapping (MoveIt's format)", file=path)
    for name, entry in limits.items():
        if name not in robot.joints:
            raise InvalidModel(f"joint '{name}' is not in the URDF", file=path,
                               element=f"joint_limits.{name}")
        if not isinstance(entry, dict):
            raise InvalidModel("must be a mapping of MoveIt limit keys", file=path,
                               element=f"joint_limits.{name}")
    scaling = []
    for key in ("default_velocity_scaling_factor", "default_acceleration_scaling_factor"):
        raw = data.get(key, 1.0)
        ok = isinstance(raw, (int, float)) and not isinstance(raw, bool) and 0 < raw <= 1
        if not ok:
            raise InvalidModel(f"{raw!r} must be a number in (0, 1]", file=path, element=key)
        scaling.append(float(raw))
    return limits, (scaling[0], scaling[1])


def apply_position_limits(robot: Robot, limits: Mapping[str, Mapping[str, object]],
                          path: Path) -> tuple[Robot, list[str]]:
    """The robot with joint_limits.yaml's ``min_position``/``max_position`` applied, and
    what was not applied.

    MoveIt reads these keys (no ``has_position_limits`` flag) and replaces the URDF's
    bounds with them, except on continuous joints. We apply them where they narrow the
    URDF's range, as ``max_velocity`` may only tighten: a figure outside the URDF's range
    would let the planner send the arm past what its model declares, so it is warned
    about and the URDF's bound kept. Everything downstream (request checks, IK,
    sampling, time parameterisation) reads the narrowed robot.

    Raises:
        InvalidModel: a figure that is not a finite number, or a range left empty.
    """
    joints = dict(robot.joints)
    warnings: list[str] = []
    for name, entry in limits.items():
        given = {k: entry[k] for k in ("min_position", "max_position") if k in entry}
        if not given:
            continue
        nums: dict[str, float] = {}
        for key, raw in given.items():
            if isinstance(raw, bool) or not isinstance(raw, (int, float)) \
                    or not np.isfinite(raw):
                raise InvalidModel(f"{raw!r} must be a finite number [rad or m]", file=path,
                                   element=f"joint_limits.{name}.{key}")
            nums[key] = float(raw)
        j = joints[name]
        lim = j.limit
        if j.type not in ("revolute", "prismatic") or lim is None or lim.lower is None \
                or lim.upper is None:
            warnings.append(f"{path.name}: joint_limits.{name}: {', '.join(given)} ignored: "
                            f"a {j.type} joint has no position range to narrow (MoveIt "
                            "refuses them too)")
            continue
        lo, hi = lim.lower, lim.upper
        if "min_position" in given:
            v = nums["min_position"]
            if v >= lo:
                lo = v
            else:
                warnings.append(f"{path.name}: joint_limits.{name}.min_position {v:g} is "
                                f"below the URDF's lower {lim.lower:g}; using the URDF's "
                                "(it may only narrow the range)")
        if "max_position" in given:
            v = nums["max_position"]
            if v <= hi:
                hi = v
            else:
                warnings.append(f"{path.name}: joint_limits.{name}.max_position {v:g} is "
                                f"above the URDF's upper {lim.upper:g}; using the URDF's "
                                "(it may only narrow the range)")
        if not lo < hi:
            raise InvalidModel(f"min_position/max_position leave [{lo:g}, {hi:g}], an empty "
                               "range", file=path, element=f"joint_limits.{name}")
        if (lo, hi) != (lim.lower, lim.upper):
            joints[name] = replace(j, limit=replace(lim, lower=lo, upper=hi))
    if joints == robot.joints:
        return robot, warnings
    return replace(robot, joints=joints), warnings


def read_initial_positions(path: Path, robot: Robot) -> dict[str, float]:
    data = read_yaml(path)
    values = data.get("initial_positions") if isinstance(data, dict) else None
    if not isinstance(values, dict):
        raise InvalidModel("needs an 'initial_positions' mapping of joint values", file=path)
    out = {}
    for name, v in values.items():
        if name not in robot.joints:
            raise InvalidModel(f"joint '{name}' is not in the URDF", file=path,
                               element=f"initial_positions.{name}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise InvalidModel(f"{v!r} is not a finite number [rad]", file=path,
                               element=f"initial_positions.{name}")
        out[str(name)] = float(v)
    return out
