"""Finding the files that configure planning: SRDF, joint limits, tool point.

ROS 2 users keep them in a separate MoveIt config package, as the MoveIt Setup Assistant
writes it (``<robot>_moveit_config`` or ``<robot>_moveit``, with ``config/<robot>.srdf``,
``config/joint_limits.yaml``, ``config/initial_positions.yaml``); the shipped arduinobot
keeps them in its description package's own ``config/``. This module decides which
folder is used and records how, so ``check``, ``info`` and the service can say so.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from arduinobot.description.errors import DescriptionError
from arduinobot.description.packages import PackageIndex, _find_manifests, package_name

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
        cartesian_limits: MoveIt's ``pilz_cartesian_limits.yaml`` (the tcp's limits in
            straight-line moves, :func:`read_cartesian_limits`).
        tasks: our ``tasks.yaml`` (named tasks, :func:`read_tasks`).
        moveit_package: the MoveIt config package folder, when one is used.
        found_by: how the folder was chosen, for humans.
    """

    srdf: Path | None = None
    joint_limits: Path | None = None
    tcp: Path | None = None
    initial_positions: Path | None = None
    cartesian_limits: Path | None = None
    tasks: Path | None = None
    moveit_package: Path | None = None
    found_by: str = "no configuration found"

    def to_json(self) -> dict[str, str | None]:
        def s(p: Path | None) -> str | None:
            return None if p is None else str(p)
        return {"srdf": s(self.srdf), "joint_limits": s(self.joint_limits), "tcp": s(self.tcp),
                "initial_positions": s(self.initial_positions),
                "cartesian_limits": s(self.cartesian_limits), "tasks": s(self.tasks),
                "moveit_package": s(self.moveit_package), "found_by": self.found_by}

    def lines(self) -> list[str]:
        """One line per file, for ``info`` and ``check``."""
        out = [f"config: {self.found_by}"]
        for label, p in (("srdf", self.srdf), ("joint_limits", self.joint_limits),
                         ("tcp", self.tcp), ("initial_positions", self.initial_positions),
                         ("cartesian_limits", self.cartesian_limits),
                         ("tasks", self.tasks)):
            out.append(f"  {label}: {p if p is not None else '(none)'}")
        return out


CARTESIAN_LIMITS_FILE = "pilz_cartesian_limits.yaml"
#: named tasks (ours, not MoveIt's): read by :func:`read_tasks`
TASKS_FILE = "tasks.yaml"


@dataclass(frozen=True)
class CartesianLimits:
    """The tcp's limits in straight-line moves (Pilz's ``cartesian_limits``).

    Attributes:
        max_trans_vel: tcp speed [m/s].
        max_trans_acc: tcp acceleration [m/s^2] while speeding up.
        max_trans_dec: tcp acceleration [m/s^2] while slowing down, negative (Pilz's sign).
        max_rot_vel: the tool's angular speed [rad/s].
        source: the file they came from, or where the defaults come from.

    A request's velocity scaling multiplies the two speeds, its acceleration scaling
    the acceleration and deceleration (Pilz's semantics).
    """

    max_trans_vel: float = 1.0
    max_trans_acc: float = 2.25
    max_trans_dec: float = -5.0
    max_rot_vel: float = 1.57
    source: str = ("defaults: the values the MoveIt Setup Assistant writes into a new "
                   "config's pilz_cartesian_limits.yaml")

    def to_json(self) -> dict[str, object]:
        return {"max_trans_vel": self.max_trans_vel, "max_trans_acc": self.max_trans_acc,
                "max_trans_dec": self.max_trans_dec, "max_rot_vel": self.max_rot_vel,
                "source": self.source}


def read_cartesian_limits(path: Path | None) -> CartesianLimits:
    """The ``cartesian_limits`` of a ``pilz_cartesian_limits.yaml``; without a file, the
    defaults of :class:`CartesianLimits` (MoveIt Setup Assistant's template: 1.0 m/s,
    2.25 m/s^2, -5.0 m/s^2, 1.57 rad/s), as Pilz itself has none and refuses to load;
    a key the file leaves out keeps its default (and the source says so).

    Raises:
        DescriptionError: unreadable YAML, or a value that is not a positive number
            (``max_trans_dec``: a negative one; a positive one is read as its magnitude
            would be ambiguous, so it is refused).
    """
    if path is None:
        return CartesianLimits()
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    except (yaml.YAMLError, OSError, UnicodeDecodeError) as e:
        raise DescriptionError(f"unreadable: {e}", file=Path(path)) from None
    block = data.get("cartesian_limits", data) if isinstance(data, dict) else None
    if not isinstance(block, dict):
        raise DescriptionError("expected a mapping 'cartesian_limits:' with max_trans_vel, "
                               "max_trans_acc, max_trans_dec, max_rot_vel", file=Path(path))
    values: dict[str, float] = {}
    for key in ("max_trans_vel", "max_trans_acc", "max_trans_dec", "max_rot_vel"):
        if key not in block:
            continue
        v = block[key]
        ok = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) \
            and (v < 0 if key == "max_trans_dec" else v > 0)
        if not ok:
            want = "a negative number [m/s^2]" if key == "max_trans_dec" else "a positive number"
            raise DescriptionError(f"cartesian_limits.{key} must be {want}, got {v!r}",
                                   file=Path(path))
        values[key] = float(v)
    missing = [k for k in ("max_trans_vel", "max_trans_acc", "max_trans_dec", "max_rot_vel")
               if k not in values]
    source = str(path) + (f" ({', '.join(missing)}: Setup Assistant defaults)" if missing
                          else "")
    return CartesianLimits(**values, source=source)


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


#: Configs shipped for robots published without one, by the URDF's robot name, and where
#: the owner's copy of that robot's folder comes from (said by ``info`` and ``check``).
SHIPPED_CONFIGS_DIR = Path(__file__).resolve().parent / "configs"
SHIPPED_CONFIG_ORIGINS = {
    "so101_new_calib": "LeRobot's SO-101 as published in github.com/TheRobotStudio/SO-ARM100, "
                       "folder Simulation/SO101 (so101_new_calib.urdf and assets/)",
}


#: The course's own task_server tasks (0 wake, 1 pick, 2 sleep), shipped with the
#: arduinobot package: a course workspace named ``arduinobot`` without a tasks.yaml of its
#: own gets them, said in ``found_by``.
COURSE_TASKS = Path(__file__).resolve().parent / "arduinobot_description" / "config" / TASKS_FILE


def shipped_config(robot_name: str) -> Path | None:
    """The config folder shipped for ``robot_name``, if any."""
    d = SHIPPED_CONFIGS_DIR / robot_name
    return d if robot_name in SHIPPED_CONFIG_ORIGINS and d.is_dir() else None


def resolve_config(
    robot_name: str,
    *,
    description_root: Path | None,
    packages: PackageIndex,
    model_folder: Path | None = None,
    moveit_config: str | Path | None = None,
    srdf: str | Path | None = None,
    joint_limits: str | Path | None = None,
) -> ConfigFiles:
    """Decide which configuration files describe the robot.

    Order: ``moveit_config`` if given; else the description package's own ``config/``
    (for a bare URDF outside any package: the ``config/`` beside it, in ``model_folder``)
    when it holds an SRDF; else a MoveIt config package found among the known packages
    and the description package's siblings; else a config shipped for this robot's name
    (:data:`SHIPPED_CONFIG_ORIGINS`). ``srdf`` and ``joint_limits`` override the single
    files.

    Raises:
        DescriptionError: ``moveit_config``, ``srdf`` or ``joint_limits`` names a path
            that does not exist.
    """
    cfg: Path | None = None
    pkg: Path | None = None
    how = "no configuration found (no SRDF: groups and named states from the URDF only)"
    desc_cfg = description_root / "config" if description_root else None
    beside = "the description package's config/"
    if desc_cfg is None and model_folder is not None:
        # a bare URDF (no package.xml), as LeRobot and onshape-to-robot publish them
        desc_cfg, beside = model_folder / "config", "the config/ beside the model file"
    if moveit_config is not None:
        pkg = Path(moveit_config).expanduser().resolve()
        if not pkg.is_dir():
            raise DescriptionError("--moveit-config is not a folder", file=pkg,
                                   hint="give the MoveIt config package folder (the one "
                                   "holding config/<robot>.srdf)")
        cfg = pkg / "config" if (pkg / "config").is_dir() else pkg
        how = "--moveit-config"
    elif default_srdf(desc_cfg, robot_name) is not None:
        cfg, how = desc_cfg, beside
    else:
        desc_name = package_name(description_root) if description_root else None
        cands = list(packages.packages.items())
        if description_root is not None:
            cands += [(package_name(p), p) for p in _find_manifests(description_root.parent)]
        found = find_moveit_package(robot_name, desc_name, cands)
        if found is not None:
            pkg, how = found
            cfg = pkg / "config"
        elif (shipped := shipped_config(robot_name)) is not None:
            cfg = shipped
            how = (f"the config shipped for {robot_name} ({SHIPPED_CONFIG_ORIGINS[robot_name]}); "
                   "--moveit-config DIR to use your own")
    dirs = [d for d in (cfg, desc_cfg) if d is not None and d.is_dir()]

    def first(name: str) -> Path | None:
        return next((d / name for d in dirs if (d / name).is_file()), None)

    files = ConfigFiles(
        srdf=default_srdf(cfg, robot_name),
        joint_limits=(cfg / "joint_limits.yaml") if cfg and (cfg / "joint_limits.yaml").is_file()
        else None,
        tcp=first("tcp.yaml"),
        initial_positions=first("initial_positions.yaml"),
        cartesian_limits=first(CARTESIAN_LIMITS_FILE),
        tasks=first(TASKS_FILE),
        moveit_package=pkg, found_by=how)
    if files.tasks is None and robot_name == "arduinobot" and COURSE_TASKS.is_file():
        # the course's task_server has these three in C++: its workspace has no file
        # (``task`` and ``serve`` say whose they are)
        files = replace(files, tasks=COURSE_TASKS)
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


@dataclass(frozen=True)
class NamedTask:
    """One entry of a ``tasks.yaml``: its name, its number (the course's
    ``task_number``; None without one), a description for humans, and its body (the
    task's JSON form, :func:`arduinobot.planner.tasks.task_from_mapping` reads it)."""

    name: str
    number: int | None
    description: str
    body: dict[str, object]


def read_tasks(path: Path) -> dict[str, NamedTask]:
    """The named tasks of a ``tasks.yaml``: ``tasks: {NAME: {number, description,
    steps, ...}}`` (a list of steps alone is a task too), by name, in file order. The
    file's ``places: {NAME: {position: [x, y, z]} | {on: OBSTACLE} | OBSTACLE}`` are
    every task's (a task's own ``places`` add to them, and win), so ``place: box, at:
    bin`` reads as the user says it.

    Raises:
        DescriptionError: unreadable YAML, no ``tasks`` mapping, an entry that is not a
            mapping or list, a number that is not an integer >= 0 or is used twice.
    """
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    except (yaml.YAMLError, OSError, UnicodeDecodeError) as e:
        raise DescriptionError(f"unreadable: {e}", file=Path(path)) from None
    block = data.get("tasks") if isinstance(data, dict) else None
    if not isinstance(block, dict):
        raise DescriptionError("expected a mapping 'tasks:' of task names to their steps",
                               file=Path(path))
    places = data.get("places", {})
    if not isinstance(places, dict):
        raise DescriptionError("places: expected a mapping of place names to {position: "
                               "[x, y, z]}, {on: OBSTACLE} or an obstacle id", file=Path(path))
    out: dict[str, NamedTask] = {}
    numbers: dict[int, str] = {}
    for name, entry in block.items():
        if isinstance(entry, list):
            entry = {"steps": entry}
        if not isinstance(entry, dict):
            raise DescriptionError(f"tasks.{name}: expected a mapping with steps",
                                   file=Path(path))
        body = dict(entry)
        if places:
            own = body.get("places", {})
            body["places"] = {**places, **own} if isinstance(own, dict) else own
        number = body.pop("number", None)
        if number is not None and (isinstance(number, bool) or not isinstance(number, int)
                                   or number < 0):
            raise DescriptionError(f"tasks.{name}.number must be an integer >= 0, got "
                                   f"{number!r}", file=Path(path))
        if number is not None and number in numbers:
            raise DescriptionError(f"tasks.{name}.number {number} is also "
                                   f"tasks.{numbers[number]}'s", file=Path(path))
        if number is not None:
            numbers[number] = str(name)
        text = str(body.pop("description", "") or "")
        out[str(name)] = NamedTask(str(name), number, text, body)
    return out


def find_task(tasks: dict[str, NamedTask], key: str | int) -> NamedTask | None:
    """The task named ``key``, or numbered ``key`` (an int or a string of digits)."""
    if isinstance(key, str) and key in tasks:
        return tasks[key]
    if isinstance(key, int) or (isinstance(key, str) and key.isdigit()):
        n = int(key)
        return next((t for t in tasks.values() if t.number == n), None)
    return None
