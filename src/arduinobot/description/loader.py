"""Loading a robot description: URDF or xacro, its package's SRDF and config.

:func:`load_description` is the one entry point the planner, service and command line
use, for the shipped arduinobot and for a user's own package alike.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from arduinobot.description.config_yaml import (
    apply_position_limits,
    read_initial_positions,
    read_joint_limits,
)
from arduinobot.description.errors import DescriptionError, InvalidModel
from arduinobot.description.model import Robot
from arduinobot.description.moveit_config import ConfigFiles, resolve_config
from arduinobot.description.packages import (
    SHIPPED_PACKAGE_DIR,
    PackageIndex,
    build_package_index,
    find_package_root,
)
from arduinobot.description.srdf import Srdf, parse_srdf
from arduinobot.description.tcp import Tcp, default_tcp, derived_groups, read_tcp
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
    tcp = read_tcp(files.tcp, robot) if files.tcp is not None else default_tcp(robot, srdf_obj)
    limits: dict[str, dict[str, object]] = {}
    scaling = (1.0, 1.0)
    if files.joint_limits is not None:
        limits, scaling = read_joint_limits(files.joint_limits, robot)
        robot, narrowed = apply_position_limits(robot, limits, files.joint_limits)
        warnings.extend(narrowed)
    initial = read_initial_positions(files.initial_positions, robot) \
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
