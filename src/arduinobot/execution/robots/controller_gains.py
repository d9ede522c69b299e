"""The servo gains of a ros2_control controllers yaml, as the twin takes them.

A user's ROS 2 workspace may hold a ``*controllers*.yaml`` beside its MoveIt config or in
a ``<robot>_controller`` package: :func:`find_controllers_yaml` finds it (not MoveIt's own
controller list), :func:`controller_gains` reads the ``gains`` of its effort-commanding
controllers (see :mod:`arduinobot.execution.robots.sim_arduinobot`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from arduinobot.description import Description
from arduinobot.execution.robots.mjcf import Gains

log = logging.getLogger(__name__)


def find_controllers_yaml(description: Description) -> Path | None:
    """A ros2_control controllers yaml next to the robot's config: a
    ``config/*controllers*.yaml`` with ``ros__parameters`` (not MoveIt's controller list)
    of the MoveIt package, the description package, or a ``<robot>_controller`` package."""
    cfg = description.config
    dirs = [p for p in (cfg.srdf.parent if cfg.srdf else None,
                        cfg.moveit_package / "config" if cfg.moveit_package else None,
                        description.package_root / "config" if description.package_root
                        else None) if p is not None]
    pkgs = description.packages.packages
    for name in (f"{description.robot.name}_controller", f"{description.robot.name}_control"):
        if name in pkgs:
            dirs.append(Path(pkgs[name]) / "config")
    for d in dict.fromkeys(dirs):
        for f in sorted(d.glob("*controllers*.yaml")) if d.is_dir() else []:
            try:
                data = yaml.safe_load(f.read_text("utf-8"))
            except yaml.YAMLError:
                log.warning("%s is not valid YAML; ignored", f)
                continue
            # a ros2_control file, not MoveIt's moveit_controllers.yaml
            if isinstance(data, dict) and ("controller_manager" in data or any(
                    isinstance(v, dict) and "ros__parameters" in v for v in data.values())):
                return f
    return None


def controller_gains(path: Path, joints: Sequence[str]) -> dict[str, Gains]:
    """``gains: {joint: {p: .., d: ..}}`` of the controllers in a ros2_control yaml that
    command ``effort`` (their PID output is a torque, so ``p`` [N m/rad] and ``d``
    [N m s/rad] are a servo's stiffness and damping), for ``joints`` with a positive
    ``p``. A position-commanded joint_trajectory_controller ignores its gains (the
    hardware holds the position), and so does the twin: such joints keep the defaults."""
    data = yaml.safe_load(path.read_text("utf-8"))
    out: dict[str, Gains] = {}

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            g = node.get("gains")
            cmd = node.get("command_interfaces") or []
            if isinstance(g, dict) and isinstance(cmd, list) and "effort" in cmd:
                for j, v in g.items():
                    if j in joints and isinstance(v, dict):
                        p, d = float(v.get("p", 0.0) or 0.0), float(v.get("d", 0.0) or 0.0)
                        if p > 0 and math.isfinite(p) and math.isfinite(d):
                            out[j] = Gains(p, max(0.0, d))
            for v in node.values():
                walk(v)
    walk(data)
    return out
