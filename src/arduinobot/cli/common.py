"""What the commands share: the model and service options, reaching the service (or its
in-process twin with --local), and turning every error into one message and exit code."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypedDict

from arduinobot.cli.argtypes import (
    FileProblem,
    JointValues,
    Mimic,
    UsageError,
    joint_map,
    key_prefix,
    xacro_arg,
)
from arduinobot.client.errors import ServiceError, ServiceUnavailable
from arduinobot.contract.errors import PlanningError
from arduinobot.contract.zconfig import DEFAULT_ENDPOINT, DEFAULT_PREFIX
from arduinobot.description import Description, DescriptionError, load_description
from arduinobot.execution.robots.base import RobotError

if TYPE_CHECKING:
    from arduinobot.client.client import PlannerClient
    from arduinobot.contract.wire import Kind

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_UNAVAILABLE = 0, 1, 2, 3
EXIT_CANCELLED = 130  # a run stopped by Ctrl-C, as a shell reports SIGINT


def add_model_args(p: argparse.ArgumentParser, *, file_arg: bool = True) -> None:
    """FILE, --package-dir and --arg, as every command that reads a model takes them."""
    if file_arg:
        p.add_argument("file", nargs="?", metavar="FILE",
                       help="a .urdf or .xacro file (default: the shipped arduinobot)")
    p.add_argument("--package-dir", action="append", default=[], metavar="DIR",
                   help="a package folder (with package.xml) or a folder of packages, for "
                   "package:// and $(find); repeatable; searched after the package holding "
                   "FILE (which wins for its own name) and before ROS_PACKAGE_PATH, "
                   "AMENT_PREFIX_PATH and FILE's workspace src/ (searched without this "
                   "option)")
    p.add_argument("--arg", action="append", default=[], metavar="NAME=VALUE",
                   type=xacro_arg, help="a xacro argument, NAME=VALUE or NAME:=VALUE; "
                   "repeatable (a name the xacro does not declare is warned about)")
    p.add_argument("--moveit-config", metavar="DIR",
                   help="the MoveIt config package (config/<robot>.srdf, joint_limits.yaml); "
                   "default: the model package's config/ if it has an SRDF, else a "
                   "<robot>_moveit_config or <robot>_moveit package found among the "
                   "package folders")
    p.add_argument("--srdf", metavar="FILE", help="an SRDF file, overriding the config's")
    p.add_argument("--joint-limits", metavar="FILE",
                   help="a MoveIt joint_limits.yaml, overriding the config's")


def add_connection_args(g: argparse._ArgumentGroup, *, timeout_help: str,
                        local_help: str) -> None:
    """--connect, --prefix, --timeout, --config and --local: how a command reaches the
    service (or plans in this process instead)."""
    g.add_argument("--connect", action="append", metavar="ENDPOINT",
                   help="the service's (or a router's) zenoh endpoint, repeatable "
                   f"(default {DEFAULT_ENDPOINT})")
    g.add_argument("--prefix", default=DEFAULT_PREFIX, type=key_prefix,
                   help="the service's key prefix")
    g.add_argument("--timeout", type=float, default=60.0, metavar="S", help=timeout_help)
    g.add_argument("--config", metavar="FILE", help="a zenoh JSON5 config for the client "
                   "session (TLS, credentials)")
    g.add_argument("--local", action="store_true", help=local_help)


def add_service_args(p: argparse.ArgumentParser) -> None:
    """--connect/--prefix/--timeout for the service, --local and the model for in-process
    (plan, fk, ik, check-state)."""
    g = p.add_argument_group("service (default) or in-process (--local)")
    add_connection_args(g, timeout_help="seconds to wait for the reply (default 60; a "
                        "plan adds its planning time)",
                        local_help="run in this process, no service (the model: "
                        "FILE/--package-dir)")
    add_model_args(p)


class ModelOptions(TypedDict):
    """The model options' keyword arguments of :func:`description.load_description`."""

    package_dirs: list[str]
    args: dict[str, str]
    moveit_config: str | None
    srdf: str | None
    joint_limits: str | None


def model_options(ns: argparse.Namespace) -> ModelOptions:
    """The keyword arguments of :func:`description.load_description` the model options
    in ``ns`` give (everything but the model file)."""
    return {"package_dirs": list(ns.package_dir), "args": dict(ns.arg),
            "moveit_config": ns.moveit_config, "srdf": ns.srdf,
            "joint_limits": ns.joint_limits}


def load_from_args(ns: argparse.Namespace) -> Description:
    """The model of FILE (or --description) and the model options, loaded once per
    command: the request, the robot and a simulation of one command share it."""
    if getattr(ns, "_description", None) is None:
        path = getattr(ns, "file", None) or getattr(ns, "description_path", None)
        ns._description = load_description(path, **model_options(ns))
    return ns._description


def client(ns: argparse.Namespace) -> PlannerClient:
    """A client session to the service the connection options name."""
    from arduinobot.client.client import PlannerClient  # zenoh: not for --local
    return PlannerClient(ns.connect or [DEFAULT_ENDPOINT], prefix=ns.prefix, timeout=ns.timeout,
                         config_file=ns.config)


def planned_by(ns: argparse.Namespace) -> str:
    """Who answers a command's requests: ``by the service at ENDPOINT`` or ``in this
    process (--local)``."""
    if ns.local:
        return "in this process (--local)"
    prefix = "" if ns.prefix == DEFAULT_PREFIX else f" (prefix {ns.prefix})"
    return f"by the service at {', '.join(ns.connect or [DEFAULT_ENDPOINT])}{prefix}"


def wrote(path: str | Path, what: str = "", *, stderr: bool = False) -> None:
    """Say that a file was written: ``wrote traj.json (123 samples)``, on stdout (on
    stderr when stdout carries data, e.g. ``--json -``)."""
    print(f"wrote {path}{f' ({what})' if what else ''}", file=sys.stderr if stderr else sys.stdout)


class Service(Protocol):
    """What a command asks of the service, or of :class:`arduinobot.service.local.LocalService`."""

    def request(self, kind: Kind, req: Mapping[str, Any]) -> dict[str, Any]: ...

    def description(self) -> dict[str, Any]: ...


@contextmanager
def connect(ns: argparse.Namespace, *, model_drives_robot: bool = False) -> Iterator[Service]:
    """The service (or with --local, its request -> reply path in this process, on the
    model of the model options).

    Args:
        model_drives_robot: the model options also choose the robot the command drives
            (``execute``), so they are not --local's alone.

    Raises:
        UsageError: model options given without --local for a command where they only
            choose what --local plans for.
    """
    scene = getattr(ns, "scene", None)
    if ns.local:
        from arduinobot.service.local import LocalService
        yield LocalService(load_from_args(ns), scene_file=scene)
        return
    if scene is not None:
        raise UsageError("--scene is for --local: the service plans against the scene it "
                         "keeps (`arduinobot scene load FILE.json` puts a saved one there)")
    if not model_drives_robot and (getattr(ns, "file", None) or any(model_options(ns).values())):
        raise UsageError("FILE, --package-dir, --arg, --moveit-config, --srdf and "
                         "--joint-limits choose the model for --local; the service plans "
                         "for the model it serves")
    with client(ns) as c:
        yield c


def joint_order(robot: Mapping[str, Any], group: str | None) -> tuple[str, ...]:
    """The joints positional values follow: ``group``'s (the default group if None), or
    every actuated joint for ``all``; ``robot`` is the ``<prefix>/description`` reply.

    Raises:
        UsageError: ``group`` is not one of the robot's.
    """
    name = group or robot["default_group"]
    groups = robot["groups"]
    if name not in groups:
        raise UsageError(f"--group '{name}' is not a group of this robot "
                         f"({', '.join(groups)})")
    return tuple(groups[name])


def joints_by_name(robot: Mapping[str, Any], values: JointValues, *, group: str | None,
                   flag: str) -> dict[str, float]:
    """``values`` as typed after ``flag`` (positional in ``group``'s order, see
    :func:`joint_order`, or by name) by joint name, a mimic's value checked against its
    leader's and dropped (:func:`arduinobot.cli.argtypes.joint_map`); ``robot`` is the
    ``<prefix>/description`` reply.

    Raises:
        UsageError: an unknown group, too many values, a mimic that disagrees.
    """
    mimics = {n: Mimic(m["leader"], m["multiplier"], m["offset"])
              for n, m in robot.get("mimic_joints", {}).items()}
    if isinstance(values, dict):
        return joint_map(values, (), flag, mimics=mimics)
    return joint_map(values, joint_order(robot, group), flag, mimics=mimics,
                     all_joints=joint_order(robot, "all"))


def run_guarded(ns: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Run the command ``ns.func``; what the user can act on becomes one message on stderr
    and the exit code: a usage error as argparse's (2, through ``parser``; a file that
    cannot be read in one line, without the usage), no service (3), a coded error of the
    service, the planner or a robot (1, with its details), a model that does not load
    (1)."""
    try:
        return ns.func(ns)
    except FileProblem as e:  # one line: the usage would bury it
        print(f"{parser.prog}: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except UsageError as e:
        parser.error(str(e))  # exits 2
    except ServiceUnavailable as e:
        print(f"arduinobot: service unavailable ({e.reason}): {e.message}", file=sys.stderr)
        return EXIT_UNAVAILABLE
    except (ServiceError, PlanningError, RobotError) as e:
        print(f"arduinobot: {e.code}: {e.message}", file=sys.stderr)
        details = {k: v for k, v in e.details.items() if k != "request_id"}
        if details:
            print(f"  details: {json.dumps(details, default=str)[:2000]}", file=sys.stderr)
    except DescriptionError as e:
        print(f"arduinobot: {type(e).__name__}: {e}", file=sys.stderr)
    return EXIT_FAIL


@contextmanager
def sigint_sets(event: threading.Event) -> Iterator[None]:
    """While active, Ctrl-C (and SIGTERM) set ``event`` instead of raising."""
    old = {sig: signal.signal(sig, lambda *_: event.set())
           for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)
