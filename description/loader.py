"""Loading a robot description: URDF or xacro, its package's SRDF and config.

:func:`load_description` is the one entry point the planner, service and command line
use, for the shipped arduinobot and for a user's own package alike.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from .errors import DescriptionError, InvalidModel, SrdfError
from .model import Origin, Robot
from .packages import SHIPPED_PACKAGE_DIR, PackageIndex, build_package_index
from .srdf import Srdf, parse_srdf
from .urdf import parse_urdf
from .xacro_expand import expand_xacro, is_xacro

_log = logging.getLogger(__name__)

DEFAULT_MODEL = SHIPPED_PACKAGE_DIR / "urdf" / "arduinobot.urdf.xacro"


@dataclass(frozen=True)
class Tcp:
    """The tool centre point: ``xyz`` [m] in ``parent_link``'s frame."""

    parent_link: str
    xyz: tuple[float, float, float]

    def origin(self) -> Origin:
        return Origin(xyz=self.xyz)


@dataclass(frozen=True)
class Description:
    """Everything known about one robot.

    Attributes:
        robot: links and joints from the URDF.
        srdf: groups, named states and disabled collision pairs, if the package has one.
        tcp: the tool centre point from ``config/tcp.yaml``, if present.
        joint_limits: the parsed ``config/joint_limits.yaml`` (``joint_limits`` mapping),
            empty if absent.
        package_root: the package folder holding the model (where ``config/`` lives).
        packages: the package index URIs were resolved with.
    """

    robot: Robot
    srdf: Srdf | None
    tcp: Tcp | None
    joint_limits: Mapping[str, Mapping[str, object]]
    package_root: Path | None
    packages: PackageIndex

    @property
    def config_dir(self) -> Path | None:
        return self.package_root / "config" if self.package_root else None


def find_package_root(path: Path) -> Path | None:
    """The nearest folder at or above ``path`` holding a ``package.xml``."""
    for d in [path, *path.parents]:
        if (d / "package.xml").is_file():
            return d
    return None


def read_model_text(
    path: str | Path | None = None,
    *,
    args: Mapping[str, str] | None = None,
    packages: PackageIndex,
) -> tuple[str, Path]:
    """The URDF text of ``path`` (xacro expanded), and the resolved path."""
    p = Path(path).expanduser().resolve() if path is not None else DEFAULT_MODEL
    if not p.is_file():
        raise DescriptionError("file does not exist", file=p,
                               hint="give a .urdf or .xacro file, or omit FILE for the "
                               "shipped arduinobot")
    text = p.read_text(encoding="utf-8", errors="replace")
    if is_xacro(p, text):
        text = expand_xacro(p, args=args, packages=packages)
    elif args:
        raise DescriptionError(f"--arg given ({', '.join(args)}) but the file is plain URDF",
                               file=p, hint="drop --arg, or pass the .xacro file")
    return text, p


def load_description(
    path: str | Path | None = None,
    *,
    package_dirs: Sequence[str | Path] = (),
    args: Mapping[str, str] | None = None,
    srdf: str | Path | None = None,
    env: Mapping[str, str] | None = None,
) -> Description:
    """Load a robot description.

    Args:
        path: a ``.urdf`` or ``.xacro`` file; None for the shipped arduinobot.
        package_dirs: extra package folders for ``package://`` and ``$(find)``, searched
            before ``ROS_PACKAGE_PATH`` and ``AMENT_PREFIX_PATH``.
        args: xacro arguments.
        srdf: an SRDF file; by default ``config/<robot name>.srdf`` of the model's
            package, or its only ``config/*.srdf``.
        env: environment to read package paths from (default ``os.environ``).

    Raises:
        DescriptionError: (a subclass naming file, element and fix) for any problem.
    """
    packages = build_package_index(package_dirs, env=env)
    text, p = read_model_text(path, args=args, packages=packages)
    robot = parse_urdf(text, packages=packages, source=p).robot
    if robot is None:  # strict parsing raises first; this guards a future lenient path
        raise InvalidModel("the model has no valid tree", file=p)
    root = find_package_root(p.parent)
    cfg = root / "config" if root else None
    srdf_obj = None
    srdf_path = Path(srdf) if srdf is not None else _default_srdf(cfg, robot.name)
    if srdf_path is not None:
        if not srdf_path.is_file():
            raise SrdfError("file does not exist", file=srdf_path)
        srdf_obj = parse_srdf(srdf_path.read_text(encoding="utf-8"), robot, source=srdf_path)
    tcp = _read_tcp(cfg / "tcp.yaml", robot) if cfg and (cfg / "tcp.yaml").is_file() else None
    limits = _read_joint_limits(cfg / "joint_limits.yaml", robot) \
        if cfg and (cfg / "joint_limits.yaml").is_file() else {}
    _log.info("loaded robot '%s' from %s: %d links, %d joints", robot.name, p,
              len(robot.links), len(robot.joints))
    return Description(robot=robot, srdf=srdf_obj, tcp=tcp, joint_limits=limits,
                       package_root=root, packages=packages)


def _default_srdf(cfg: Path | None, robot_name: str) -> Path | None:
    if cfg is None or not cfg.is_dir():
        return None
    named = cfg / f"{robot_name}.srdf"
    if named.is_file():
        return named
    found = sorted(cfg.glob("*.srdf"))
    return found[0] if len(found) == 1 else None


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
        vec = tuple(float(v) for v in xyz)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        vec = ()
    if len(vec) != 3 or not np.all(np.isfinite(vec)):
        raise InvalidModel(f"xyz {xyz!r} must be 3 finite numbers [m]", file=path,
                           element="tcp.xyz")
    return Tcp(parent_link=str(parent), xyz=vec)  # type: ignore[arg-type]


def _read_joint_limits(path: Path, robot: Robot) -> dict[str, dict[str, object]]:
    data = _read_yaml(path)
    limits = data.get("joint_limits") if isinstance(data, dict) else None
    if not isinstance(limits, dict):
        raise InvalidModel("needs a 'joint_limits' mapping (MoveIt's format)", file=path)
    for name, entry in limits.items():
        if name not in robot.joints:
            raise InvalidModel(f"joint '{name}' is not in the URDF", file=path,
                               element=f"joint_limits.{name}")
        if not isinstance(entry, dict):
            raise InvalidModel("must be a mapping of MoveIt limit keys", file=path,
                               element=f"joint_limits.{name}")
    return limits
