"""Finding the files that configure planning: SRDF, joint limits, tool point.

ROS 2 users keep them in a separate MoveIt config package, as the MoveIt Setup Assistant
writes it (``<robot>_moveit_config`` or ``<robot>_moveit``, with ``config/<robot>.srdf``,
``config/joint_limits.yaml``, ``config/initial_positions.yaml``); the shipped arduinobot
keeps them in its description package's own ``config/``. This module decides which
folder is used and records how, so ``check``, ``info`` and the service can say so.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from .errors import DescriptionError
from .packages import PackageIndex, _find_manifests, package_name

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ConfigFiles:
    """The planning configuration files in use (None where there is none).

    Attributes:
        srdf: groups, named states, disabled collision pairs.
        joint_limits: MoveIt's ``joint_limits.yaml``.
        tcp: our ``tcp.yaml`` (the tool point).
        initial_positions: MoveIt's ``initial_positions.yaml`` (what the hardware
            reports before its first command).
        moveit_package: the MoveIt config package folder, when one is used.
        found_by: how the folder was chosen, for humans.
    """

    srdf: Path | None = None
    joint_limits: Path | None = None
    tcp: Path | None = None
    initial_positions: Path | None = None
    moveit_package: Path | None = None
    found_by: str = "no configuration found"

    def to_json(self) -> dict[str, str | None]:
        def s(p: Path | None) -> str | None:
            return None if p is None else str(p)
        return {"srdf": s(self.srdf), "joint_limits": s(self.joint_limits), "tcp": s(self.tcp),
                "initial_positions": s(self.initial_positions),
                "moveit_package": s(self.moveit_package), "found_by": self.found_by}

    def lines(self) -> list[str]:
        """One line per file, for ``info`` and ``check``."""
        out = [f"config: {self.found_by}"]
        for label, p in (("srdf", self.srdf), ("joint_limits", self.joint_limits),
                         ("tcp", self.tcp), ("initial_positions", self.initial_positions)):
            out.append(f"  {label}: {p if p is not None else '(none)'}")
        return out


def default_srdf(cfg: Path | None, robot_name: str) -> Path | None:
    """``cfg/<robot>.srdf``, else the only ``cfg/*.srdf``, else None."""
    if cfg is None or not cfg.is_dir():
        return None
    named = cfg / f"{robot_name}.srdf"
    if named.is_file():
        return named
    found = sorted(cfg.glob("*.srdf"))
    return found[0] if len(found) == 1 else None


def _setup_assistant_names(pkg: Path) -> str | None:
    """The description package a MoveIt config package's ``.setup_assistant`` names."""
    f = pkg / ".setup_assistant"
    if not f.is_file():
        return None
    try:
        data = yaml.safe_load(f.read_text(encoding="utf-8"))
    except (yaml.YAMLError, OSError, UnicodeDecodeError) as e:
        _log.warning("%s: unreadable (%s); ignored", f, e)
        return None
    urdf = (data or {}).get("moveit_setup_assistant_config", {}).get("urdf") \
        if isinstance(data, dict) else None
    if isinstance(urdf, dict):
        name = urdf.get("package") or urdf.get("package_name")
        return str(name) if name else None
    return None


def find_moveit_package(robot_name: str, description_package: str | None,
                        candidates: Iterable[tuple[str, Path]]) -> tuple[Path, str] | None:
    """The MoveIt config package for this robot among ``candidates`` (name, folder), and
    why it was chosen: named ``<robot>_moveit_config`` / ``<robot>_moveit`` (or after the
    description package, ``foo_description`` -> ``foo_moveit_config``), else one whose
    ``.setup_assistant`` names the description package."""
    pkgs = dict(candidates)
    stems = [robot_name]
    if description_package and description_package.endswith("_description"):
        stems.append(description_package.removesuffix("_description"))
    for stem in dict.fromkeys(stems):
        for suffix in ("_moveit_config", "_moveit"):
            name = stem + suffix
            if name in pkgs:
                return pkgs[name], f"package {name} (named after the robot)"
    if description_package:
        for name, folder in sorted(pkgs.items()):
            if _setup_assistant_names(folder) == description_package:
                return folder, f"package {name} (its .setup_assistant names {description_package})"
    return None


def resolve_config(
    robot_name: str,
    *,
    description_root: Path | None,
    packages: PackageIndex,
    moveit_config: str | Path | None = None,
    srdf: str | Path | None = None,
    joint_limits: str | Path | None = None,
) -> ConfigFiles:
    """Decide which configuration files describe the robot.

    Order: ``moveit_config`` if given; else the description package's own ``config/``
    when it holds an SRDF; else a MoveIt config package found among the known packages
    and the description package's siblings. ``srdf`` and ``joint_limits`` override the
    single files.

    Raises:
        DescriptionError: ``moveit_config``, ``srdf`` or ``joint_limits`` names a path
            that does not exist.
    """
    cfg: Path | None = None
    pkg: Path | None = None
    how = "no configuration found (no SRDF: groups and named states from the URDF only)"
    desc_cfg = description_root / "config" if description_root else None
    if moveit_config is not None:
        pkg = Path(moveit_config).expanduser().resolve()
        if not pkg.is_dir():
            raise DescriptionError("--moveit-config is not a folder", file=pkg,
                                   hint="give the MoveIt config package folder (the one "
                                   "holding config/<robot>.srdf)")
        cfg = pkg / "config" if (pkg / "config").is_dir() else pkg
        how = "--moveit-config"
    elif default_srdf(desc_cfg, robot_name) is not None:
        cfg, how = desc_cfg, "the description package's config/"
    else:
        desc_name = package_name(description_root) if description_root else None
        cands = list(packages.packages.items())
        if description_root is not None:
            cands += [(package_name(p), p) for p in _find_manifests(description_root.parent)]
        found = find_moveit_package(robot_name, desc_name, cands)
        if found is not None:
            pkg, how = found
            cfg = pkg / "config"
    dirs = [d for d in (cfg, desc_cfg) if d is not None and d.is_dir()]

    def first(name: str) -> Path | None:
        return next((d / name for d in dirs if (d / name).is_file()), None)

    files = ConfigFiles(
        srdf=default_srdf(cfg, robot_name),
        joint_limits=(cfg / "joint_limits.yaml") if cfg and (cfg / "joint_limits.yaml").is_file()
        else None,
        tcp=first("tcp.yaml"),
        initial_positions=first("initial_positions.yaml"),
        moveit_package=pkg, found_by=how)
    for label, override in (("srdf", srdf), ("joint_limits", joint_limits)):
        if override is None:
            continue
        p = Path(override).expanduser().resolve()
        if not p.is_file():
            raise DescriptionError(f"--{label.replace('_', '-')} file does not exist", file=p)
        found_by = f"{files.found_by}; --{label.replace('_', '-')} {p}"
        files = (replace(files, srdf=p, found_by=found_by) if label == "srdf"
                 else replace(files, joint_limits=p, found_by=found_by))
    return files
