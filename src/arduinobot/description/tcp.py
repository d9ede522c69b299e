"""The tool centre point: what it is, the default without a tcp file, and ``tcp.yaml``.

The point pose goals, straight lines and held orientations are of; a model without an
SRDF also takes its groups from it (:func:`derived_groups`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from arduinobot.description.config_yaml import read_yaml
from arduinobot.description.errors import InvalidModel
from arduinobot.description.model import Origin, Robot, rpy_matrix
from arduinobot.description.srdf import Srdf


@dataclass(frozen=True)
class Tcp:
    """The tool centre point: ``xyz`` [m] in ``parent_link``'s frame, and the tool
    frame's orientation there, URDF roll-pitch-yaw ``rpy`` [rad] (pose goals and held
    orientations are of this frame); ``source`` says where it came from
    (``config/tcp.yaml``, or the rule that chose a default)."""

    parent_link: str
    xyz: tuple[float, float, float]
    source: str = "config/tcp.yaml"
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def origin(self) -> Origin:
        return Origin(xyz=self.xyz, rpy=self.rpy)

    def rotation(self) -> np.ndarray:
        """The tool frame in ``parent_link``'s, shape (3, 3)."""
        return rpy_matrix(self.rpy)


def main_chain_tip(robot: Robot) -> str:
    """The last link of the robot's main chain: from the root, follow the one child
    joint whose subtree moves, until the tree ends or branches (e.g. into fingers).
    Rigid side branches (a camera on a fixed joint) are not branches here."""
    children = robot.child_joints
    moves: dict[str, bool] = {}

    def has_movable(link: str) -> bool:
        if link not in moves:
            moves[link] = any(j.movable or has_movable(j.child) for j in children.get(link, ()))
        return moves[link]

    link = robot.root
    while True:
        live = [j for j in children.get(link, ()) if j.movable or has_movable(j.child)]
        if len(live) != 1:
            return link
        link = live[0].child


def default_tcp(robot: Robot, srdf: Srdf | None) -> Tcp:
    """The tool point without a tcp file: the origin of the default group's tool link
    (an SRDF end effector's ``parent_link``, else the tip of the group's chain), or
    without an SRDF the end of the robot's main chain."""
    if srdf is not None:
        group = srdf.default_group()
        tip = srdf.tip_link(group) if group else None
        if tip is not None:
            eff = next((e for e in srdf.end_effectors if e.parent_group == group), None)
            why = (f"end effector '{eff.name}' parent_link" if eff is not None
                   else f"tip of group '{group}'")
            return Tcp(tip, (0.0, 0.0, 0.0), f"default: origin of {tip} ({why})")
    frame = tool_frame(robot)
    if frame is not None:
        return Tcp(frame, (0.0, 0.0, 0.0),
                   f"default: origin of {frame} (the model's tool frame: a massless frame "
                   "on a fixed joint named like one)")
    tip = main_chain_tip(robot)
    return Tcp(tip, (0.0, 0.0, 0.0), f"default: origin of {tip} (end of the main chain)")


# Names a tool frame goes by: ROS-Industrial's tool0, onshape-to-robot's *_frame_link,
# and the usual tcp / tool / ee / end_effector links.
_TOOL_FRAME = re.compile(r"^tool0$|tcp|tool|_frame_link$|^ee(_link)?$|end_?effector",
                         re.IGNORECASE)


def tool_frame(robot: Robot) -> str | None:
    """The model's tool frame, if it has one: the deepest leaf among its frame links
    (:attr:`Robot.frame_links`) whose name reads like a tool frame; None otherwise."""
    leaves = [f for f in robot.frame_links
              if not robot.child_joints.get(f) and _TOOL_FRAME.search(f)]
    if not leaves:
        return None
    return max(leaves, key=lambda f: len(robot.link_path(f)))


def derived_groups(robot: Robot, tcp: Tcp) -> dict[str, tuple[str, ...]]:
    """Groups for a model without an SRDF: ``arm``, the actuated joints from the root to
    the tool point's link, and ``gripper``, the others, when the tool point leaves some
    out (a jaw beside the tool frame); else none (every joint is the arm)."""
    actuated = robot.actuated_joints
    arm = tuple(j.name for j in robot.link_path(tcp.parent_link) if j.name in actuated)
    rest = tuple(j for j in actuated if j not in arm)
    if not arm or not rest:
        return {}
    return {"arm": arm, "gripper": rest}


def read_tcp(path: Path, robot: Robot) -> Tcp:
    data = read_yaml(path)
    tcp = data.get("tcp") if isinstance(data, dict) else None
    if not isinstance(tcp, dict):
        raise InvalidModel("needs a 'tcp' mapping with parent_link and xyz", file=path)
    parent = tcp.get("parent_link")
    if parent not in robot.links:
        raise InvalidModel(f"parent_link '{parent}' is not a link of the URDF", file=path,
                           element="tcp.parent_link")
    xyz = tcp.get("xyz")
    try:
        vec = tuple(float(v) for v in xyz) if xyz is not None else ()
    except (TypeError, ValueError):
        vec = ()
    if len(vec) != 3 or not np.all(np.isfinite(vec)):
        raise InvalidModel(f"xyz {xyz!r} must be 3 finite numbers [m]", file=path,
                           element="tcp.xyz")
    rpy_raw = tcp.get("rpy", (0.0, 0.0, 0.0))
    try:
        rpy = tuple(float(v) for v in rpy_raw)
    except (TypeError, ValueError):
        rpy = ()
    if len(rpy) != 3 or not np.all(np.isfinite(rpy)):
        raise InvalidModel(f"rpy {rpy_raw!r} must be 3 finite numbers [rad]", file=path,
                           element="tcp.rpy")
    return Tcp(parent_link=str(parent), xyz=(vec[0], vec[1], vec[2]),
               rpy=(rpy[0], rpy[1], rpy[2]))
