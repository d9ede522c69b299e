"""Options every model-reading command shares, and turning errors into exit codes."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from description import Description, DescriptionError, load_description

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2


def add_model_args(p: argparse.ArgumentParser, *, file_arg: bool = True) -> None:
    """FILE, --package-dir and --arg, as every command that reads a model takes them."""
    if file_arg:
        p.add_argument("file", nargs="?", metavar="FILE",
                       help="a .urdf or .xacro file (default: the shipped arduinobot)")
    p.add_argument("--package-dir", action="append", default=[], metavar="DIR",
                   help="a package folder (with package.xml) or a folder of packages, for "
                   "package:// and $(find); repeatable; searched before ROS_PACKAGE_PATH "
                   "and AMENT_PREFIX_PATH")
    p.add_argument("--arg", action="append", default=[], metavar="NAME=VALUE",
                   help="a xacro argument; repeatable")
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
                   "(default tcp/127.0.0.1:7447)")
    g.add_argument("--prefix", default="arduinobot", help="the service's key prefix")
    g.add_argument("--timeout", type=float, default=60.0, metavar="S", help=timeout_help)
    g.add_argument("--config", metavar="FILE", help="a zenoh JSON5 config for the client "
                   "session (TLS, credentials)")
    g.add_argument("--local", action="store_true", help=local_help)


def parse_xacro_args(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise SystemExit(f"arduinobot: error: --arg '{item}' must be NAME=VALUE")
        out[name] = value
    return out


def model_options(ns: argparse.Namespace) -> dict[str, object]:
    """The keyword arguments of :func:`description.load_description` the model options
    in ``ns`` give (everything but the model file)."""
    return {"package_dirs": list(ns.package_dir), "args": parse_xacro_args(ns.arg),
            "moveit_config": ns.moveit_config, "srdf": ns.srdf,
            "joint_limits": ns.joint_limits}


def model_chosen(ns: argparse.Namespace) -> bool:
    """True if any model option (FILE included) was given."""
    return bool(getattr(ns, "file", None) or ns.package_dir or ns.arg or ns.moveit_config
                or ns.srdf or ns.joint_limits)


def load_from_args(ns: argparse.Namespace) -> Description:
    return load_description(getattr(ns, "file", None), **model_options(ns))  # type: ignore[arg-type]


def local_description(ns: argparse.Namespace) -> Description:
    """:func:`load_from_args`, once per command: the joint order, the request and a
    simulation of one command share the loaded model."""
    if getattr(ns, "_description", None) is None:
        ns._description = load_from_args(ns)
    return ns._description


def run_guarded(fn: Callable[[argparse.Namespace], int], ns: argparse.Namespace) -> int:
    """Run a command; a model error becomes one clear line on stderr and exit 1."""
    try:
        return fn(ns)
    except DescriptionError as e:
        print(f"arduinobot: {type(e).__name__}: {e}", file=sys.stderr)
        return EXIT_FAIL
