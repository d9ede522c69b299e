"""Which ros2_control controller moves which joints, and a trajectory cut per controller.

What MoveIt's ``moveit_simple_controller_manager`` does: ``moveit_controllers.yaml``
names the controllers and their joints (:func:`read_moveit_controllers`), a trajectory is
split per controller (:func:`split_trajectory`), and each part becomes a
``trajectory_msgs/msg/JointTrajectory`` (:func:`joint_trajectory`) that
:class:`arduinobot.ros2.trajectory_target.TrajectoryTarget` sends to its controller. Nothing here
imports ``src/arduinobot/client/``, ``src/arduinobot/service/`` or ``src/arduinobot/execution/``: the caller hands plain arrays.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arduinobot.ros2.errors import InvalidOption, NoController
from arduinobot.ros2.wire.types import TypeStore

log = logging.getLogger(__name__)

JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"


# -- which controller moves which joints ----------------------------------------------------

@dataclass(frozen=True)
class Controller:
    """A controller MoveIt knows: its ``name`` (``/<name>/...``), its joints, and the
    action's namespace under it (``/<name>/<action_ns>``)."""

    name: str
    joints: tuple[str, ...]
    action_ns: str = "follow_joint_trajectory"

    @property
    def action(self) -> str:
        return f"{self.name}/{self.action_ns}"

    @property
    def topic(self) -> str:
        return f"{self.name}/joint_trajectory"


def read_moveit_controllers(path: str | Path) -> tuple[Controller, ...]:
    """The FollowJointTrajectory controllers of a MoveIt ``moveit_controllers.yaml``
    (``moveit_simple_controller_manager.controller_names`` and, per name, ``joints`` and
    ``action_ns``), in the file's order. A controller of another type (a
    GripperCommand) is skipped with a warning.

    Raises:
        InvalidOption: the file is unreadable or not in that shape (naming what is wrong).
    """
    import yaml

    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as e:
        raise InvalidOption("moveit_controllers.yaml", str(p), f"unreadable: {e}") from e
    manager = data.get("moveit_simple_controller_manager") if isinstance(data, dict) else None
    names = manager.get("controller_names") if isinstance(manager, dict) else None
    if not isinstance(manager, dict) or not isinstance(names, list) \
            or not all(isinstance(n, str) for n in names):
        raise InvalidOption("moveit_controllers.yaml", str(p), "no moveit_simple_controller_"
                            "manager.controller_names list")
    out = []
    for name in names:
        entry = manager.get(name)
        if not isinstance(entry, dict) or not isinstance(entry.get("joints"), list):
            raise InvalidOption("moveit_controllers.yaml", str(p),
                                f"controller {name} has no joints list")
        kind = entry.get("type", "FollowJointTrajectory")
        if kind != "FollowJointTrajectory":
            log.warning("%s: controller %s is a %s, not a FollowJointTrajectory: skipped",
                        p, name, kind)
            continue
        out.append(Controller(name, tuple(str(j) for j in entry["joints"]),
                              str(entry.get("action_ns") or "follow_joint_trajectory")))
    return tuple(out)


@dataclass(frozen=True)
class Part:
    """The piece of a trajectory one controller plays: ``joint_names`` (the trajectory's
    order), ``times`` (m,) [s] and ``positions``/``velocities``/``accelerations`` (m, k),
    the last two None where the plan has none."""

    controller: Controller
    joint_names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None

    @property
    def duration(self) -> float:
        return float(self.times[-1])


def split_trajectory(joint_names: Sequence[str], times: Sequence[float] | np.ndarray,
                     columns: Mapping[str, np.ndarray], controllers: Sequence[Controller]
                     ) -> list[Part]:
    """The trajectory (``columns``: ``positions`` and optionally ``velocities``,
    ``accelerations``, each (m, dof), NaN rows where a point lacks one) cut per
    controller; controllers that own none of its joints get nothing.

    Raises:
        NoController: a joint no controller owns, or one two controllers claim.
    """
    owner: dict[str, Controller] = {}
    for c in controllers:
        for j in c.joints:
            if j in owner and j in joint_names:
                raise NoController([j], f"both {owner[j].name} and {c.name} claim it",
                                   controllers=[x.name for x in controllers])
            owner.setdefault(j, c)
    orphans = [j for j in joint_names if j not in owner]
    if orphans:
        raise NoController(orphans, "no controller moves them",
                           controllers=[c.name for c in controllers])
    t = np.asarray(times, float)
    parts = []
    for c in controllers:
        idx = [i for i, j in enumerate(joint_names) if owner[j] is c]
        if not idx:
            continue
        missing = [j for j in c.joints if j not in joint_names]
        if missing:
            log.warning("%s also has %s, which the trajectory does not move: the controller "
                        "rejects the goal unless allow_partial_joints_goal is set",
                        c.name, ", ".join(missing))
        positions = _cut(columns, "positions", idx)
        if positions is None:
            raise InvalidOption("trajectory", "positions", "every point needs positions")
        parts.append(Part(c, tuple(joint_names[i] for i in idx), t, positions,
                          _cut(columns, "velocities", idx),
                          _cut(columns, "accelerations", idx)))
    return parts


def _cut(columns: Mapping[str, np.ndarray], key: str, idx: list[int]) -> np.ndarray | None:
    col = columns.get(key)
    if col is None:
        return None
    sub = np.asarray(col, float)[:, idx]
    return None if np.isnan(sub).all() else sub


def joint_trajectory(types: TypeStore, part: Part, *, stamp_ns: int = 0) -> Any:
    """The ``trajectory_msgs/msg/JointTrajectory`` of ``part``; stamp 0 (the default)
    means "start on receipt" to joint_trajectory_controller."""
    def row(a: np.ndarray | None, k: int) -> np.ndarray:
        if a is None or np.isnan(a[k]).any():
            return np.zeros(0)
        return np.ascontiguousarray(a[k], dtype=np.float64)

    points = []
    for k, t in enumerate(part.times):
        ns = round(float(t) * 1e9)
        points.append(types.message(
            "trajectory_msgs/msg/JointTrajectoryPoint", positions=row(part.positions, k),
            velocities=row(part.velocities, k), accelerations=row(part.accelerations, k),
            effort=np.zeros(0),
            time_from_start=types.message("builtin_interfaces/msg/Duration",
                                          sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
    stamp = types.message("builtin_interfaces/msg/Time", sec=stamp_ns // 1_000_000_000,
                          nanosec=stamp_ns % 1_000_000_000)
    return types.message(JOINT_TRAJECTORY,
                         header=types.message("std_msgs/msg/Header", stamp=stamp, frame_id=""),
                         joint_names=list(part.joint_names), points=points)
