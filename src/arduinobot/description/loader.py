"""Loading a robot description: URDF or xacro, its package's SRDF and config.

:func:`load_description` is the one entry point the planner, service and command line
use, for the shipped arduinobot and for a user's own package alike.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from arduinobot.description.errors import DescriptionError, InvalidModel
from arduinobot.description.model import Origin, Robot, rpy_matrix
from arduinobot.description.moveit_config import ConfigFiles, resolve_config
from arduinobot.description.packages import (
    SHIPPED_PACKAGE_DIR,
    PackageIndex,
    build_package_index,
    find_package_root,
)
from arduinobot.description.srdf import Srdf, parse_srdf
from arduinobot.description.urdf import parse_urdf
from arduinobot.description.xacro_expand import expand_xacro_report, is_xacro

_log = logging.getLogger(__name__)

DEFAULT_MODEL = SHIPPED_PACKAGE_DIR / "urdf" / "arduinobot.urdf.xacro"

#: What the shipped model's size means for an owner of the printed arm (``info`` and the
#: ``size_note`` of ``<prefix>/description``); the figures are robot-model.md's.
SHIPPED_SIZE_NOTE = (
    "the shipped arduinobot follows the course video's figures (shoulder joint 0.307 m "
    "above the base, centimetre meshes at scale 0.01): ten times the printed arm of the "
    "course's published packages (0.0307 m, millimetre meshes at scale 0.001). Joint "
    "goals are the same on both; for tcp positions and obstacles, plan with your own "
    "workspace's model (e.g. arduinobot serve "
    "~/ws/src/arduinobot_description/urdf/arduinobot.urdf.xacro)")


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


@dataclass(frozen=True)
class Description:
    """Everything known about one robot.

    Attributes:
        robot: links and joints from the URDF.
        srdf: groups, named states and disabled collision pairs, if the package has one.
        tcp: the tool centre point from ``config/tcp.yaml``, if present.
        joint_limits: the parsed ``config/joint_limits.yaml`` (``joint_limits`` mapping),
            empty if absent.
        package_root: the package folder holding the model.
        packages: the package index URIs were resolved with.
        config: which SRDF, joint limits, tcp and initial positions files were used, and
            how they were found (a MoveIt config package, or the model's own config/).
        default_velocity_scaling, default_acceleration_scaling: MoveIt's
            ``default_*_scaling_factor`` of joint_limits.yaml, in (0, 1] (1 if absent):
            the scaling of a request that sets none.
        initial_positions: joint values [rad] the hardware starts at
            (``initial_positions.yaml``), empty if absent.
        warnings: what loading tolerated (open meshes are the checker's business; this is
            e.g. a ``<material>`` inside ``<geometry>`` or SRDF pairs naming lost links).
        derived: without an SRDF, the groups derived from the tool point
            (:func:`derived_groups`: ``arm`` and ``gripper``), else empty.
    """

    robot: Robot
    srdf: Srdf | None
    tcp: Tcp | None
    joint_limits: Mapping[str, Mapping[str, object]]
    package_root: Path | None
    packages: PackageIndex
    config: ConfigFiles = field(default_factory=ConfigFiles)
    default_velocity_scaling: float = 1.0
    default_acceleration_scaling: float = 1.0
    initial_positions: Mapping[str, float] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    derived: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    def summary(self) -> dict[str, object]:
        """What a request may name for this robot, JSON-ready: ``groups`` (name -> its
        actuated joints, ``all`` included), ``default_group``, ``named_states`` (name,
        group, values) and ``actuated_joints``."""
        srdf = self.srdf
        return {"groups": self.group_joints(), "default_group": self.default_group(),
                "named_states": [] if srdf is None else [
                    {"name": s.name, "group": s.group, "values": dict(s.values)}
                    for s in srdf.states],
                "actuated_joints": list(self.robot.actuated_joints)}

    def group_joints(self) -> dict[str, list[str]]:
        """Each planning group's actuated joints, by group name (``all``: every one)."""
        srdf = self.srdf
        actuated = self.robot.actuated_joints
        groups = {g.name: [j for j in g.joints if j in actuated]
                  for g in (srdf.groups.values() if srdf is not None else ())}
        if srdf is None:
            groups.update({k: list(v) for k, v in self.derived.items()})
        groups["all"] = list(actuated)
        return groups

    @property
    def size_note(self) -> str | None:
        """For the shipped model, :data:`SHIPPED_SIZE_NOTE`; None for a user's own."""
        return SHIPPED_SIZE_NOTE if self.package_root == SHIPPED_PACKAGE_DIR else None

    def default_group(self) -> str:
        """The planning group of a request that names none (see
        :meth:`Srdf.default_group`); without an SRDF, the derived ``arm`` if the tool
        point leaves a gripper out, else ``all``."""
        if self.srdf is None:
            return "arm" if "arm" in self.derived else "all"
        return self.srdf.default_group() or "all"


def model_path(path: str | Path | None) -> Path:
    """The model file ``path`` names, resolved (the shipped arduinobot's for None)."""
    return Path(path).expanduser().resolve() if path is not None else DEFAULT_MODEL


def read_model_text(
    path: str | Path | None = None,
    *,
    args: Mapping[str, str] | None = None,
    packages: PackageIndex,
) -> tuple[str, Path]:
    """The URDF text of ``path`` (xacro expanded), and the resolved path."""
    text, p, _ = read_model(path, args=args, packages=packages)
    return text, p


def read_model(
    path: str | Path | None = None,
    *,
    args: Mapping[str, str] | None = None,
    packages: PackageIndex,
) -> tuple[str, Path, tuple[str, ...]]:
    """The URDF text of ``path`` (xacro expanded), the resolved path, and what the
    expansion tolerated (an ``--arg`` the xacro does not declare)."""
    p = model_path(path)
    if not p.is_file():
        raise DescriptionError("file does not exist", file=p,
                               hint="give a .urdf or .xacro file, or omit FILE for the "
                               "shipped arduinobot")
    text = p.read_text(encoding="utf-8", errors="replace")
    if is_xacro(p, text):
        expansion = expand_xacro_report(p, args=args, packages=packages)
        return expansion.text, p, expansion.warnings
    if args:
        raise DescriptionError(f"--arg given ({', '.join(args)}) but the file is plain URDF",
                               file=p, hint="drop --arg, or pass the .xacro file")
    return text, p, ()


def load_description(
    path: str | Path | None = None,
    *,
    package_dirs: Sequence[str | Path] = (),
    args: Mapping[str, str] | None = None,
    moveit_config: str | Path | None = None,
    srdf: str | Path | None = None,
    joint_limits: str | Path | None = None,
    env: Mapping[str, str] | None = None,
) -> Description:
    """Load a robot description and the files that configure planning for it.

    Args:
        path: a ``.urdf`` or ``.xacro`` file; None for the shipped arduinobot.
        package_dirs: extra package folders for ``package://`` and ``$(find)``, searched
            after the model's own package and before ``ROS_PACKAGE_PATH``,
            ``AMENT_PREFIX_PATH`` and the model's workspace (the order:
            :mod:`arduinobot.description.packages`).
        args: xacro arguments.
        moveit_config: a MoveIt config package folder. By default: the model package's
            own ``config/`` if it has an SRDF, else a ``<robot>_moveit_config`` or
            ``<robot>_moveit`` package (or one whose ``.setup_assistant`` names the
            description package) among the known packages and the model package's
            siblings (see :func:`arduinobot.description.moveit_config.resolve_config`).
        srdf: an SRDF file, overriding the config package's.
        joint_limits: a joint_limits.yaml, overriding the config package's.
        env: environment to read package paths from (default ``os.environ``).

    Raises:
        DescriptionError: (a subclass naming file, element and fix) for any problem.
    """
    packages = build_package_index(package_dirs, env=env, model=model_path(path))
    text, p, expansion_warnings = read_model(path, args=args, packages=packages)
    report = parse_urdf(text, packages=packages, source=p)
    robot = report.robot
    if robot is None:  # strict parsing raises first; this guards a future lenient path
        raise InvalidModel("the model has no valid tree", file=p)
    root = find_package_root(p.parent)
    files = resolve_config(robot.name, description_root=root, packages=packages,
                           model_folder=p.parent,
                           moveit_config=moveit_config, srdf=srdf, joint_limits=joint_limits)
    warnings = [*packages.warnings, *expansion_warnings, *(str(w) for w in report.warnings)]
    srdf_obj = None
    if files.srdf is not None:
        srdf_obj = parse_srdf(files.srdf.read_text(encoding="utf-8"), robot, source=files.srdf)
        warnings.extend(f"{files.srdf.name}: {w}" for w in srdf_obj.warnings)
    tcp = _read_tcp(files.tcp, robot) if files.tcp is not None else default_tcp(robot, srdf_obj)
    limits: dict[str, dict[str, object]] = {}
    scaling = (1.0, 1.0)
    if files.joint_limits is not None:
        limits, scaling = _read_joint_limits(files.joint_limits, robot)
        robot, narrowed = apply_position_limits(robot, limits, files.joint_limits)
        warnings.extend(narrowed)
    initial = _read_initial_positions(files.initial_positions, robot) \
        if files.initial_positions is not None else {}
    for w in warnings:
        _log.warning("%s", w)
    _log.info("loaded robot '%s' from %s: %d links, %d joints; %s", robot.name, p,
              len(robot.links), len(robot.joints), "; ".join(files.lines()))
    return Description(robot=robot, srdf=srdf_obj, tcp=tcp, joint_limits=limits,
                       package_root=root, packages=packages, config=files,
                       default_velocity_scaling=scaling[0],
                       default_acceleration_scaling=scaling[1], initial_positions=initial,
                       warnings=tuple(warnings),
                       derived=derived_groups(robot, tcp) if srdf_obj is None else {})


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


def _read_yaml(path: Path) -> object:
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as e:
        raise DescriptionError(f"not valid YAML: {e}", file=path) from e


def _read_tcp(path: Path, robot: Robot) -> Tcp:
    data = _read_yaml(path)
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


def _read_joint_limits(path: Path, robot: Robot
                       ) -> tuple[dict[str, dict[str, object]], tuple[float, float]]:
    """MoveIt's joint_limits.yaml: per-joint entries, and the default velocity and
    acceleration scaling factors (1 when absent)."""
    data = _read_yaml(path)
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


def _read_initial_positions(path: Path, robot: Robot) -> dict[str, float]:
    data = _read_yaml(path)
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
