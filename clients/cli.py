"""The `arduinobot` command: one entry point, one subcommand per job."""

from __future__ import annotations

import argparse
import logging
import sys
from functools import partial

from . import cmd_execute, cmd_model, cmd_plan, cmd_serve, cmd_srdf, cmd_state, cmd_view
from .common import run_guarded

# Commands that run OMPL in this process (the second set with --local only), whose own log
# follows -v (quiet by default); a remote plan must not import OMPL (~1 s).
_OMPL_ALWAYS, _OMPL_LOCAL = {"serve", "srdf", "view"}, {"plan", "ik", "execute"}
_COMMANDS = [cmd_model, cmd_serve, cmd_srdf, cmd_view, cmd_plan, cmd_state, cmd_execute]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="arduinobot",
        description="Motion planning for the arduinobot arm (and your own URDF): load and "
        "check models without ROS, plan collision-free paths, time them within the "
        "motors' limits, and serve it all over Zenoh.",
        epilog="Every command that reads a model takes FILE (URDF or xacro; default: the "
        "shipped arduinobot) and --package-dir DIR, and honours ROS_PACKAGE_PATH and "
        "AMENT_PREFIX_PATH. 'arduinobot COMMAND --help' explains each command.")
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="log more (-v info, -vv debug) to stderr")
    # every command's description and examples keep their line breaks
    raw = partial(argparse.ArgumentParser, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=raw)
    for mod in _COMMANDS:
        mod.register(sub)
    for sp in sub.choices.values():  # a usage error names its command, as argparse's do
        sp.set_defaults(command_parser=sp)
    return p


def main(argv: list[str] | None = None) -> int:
    ns = build_parser().parse_args(argv)
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(ns.verbose, 2)]
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        stream=sys.stderr)
    if ns.command in _OMPL_ALWAYS or (ns.command in _OMPL_LOCAL and ns.local):
        from planner.planning.paths import set_ompl_log_level
        set_ompl_log_level(["none", "info", "debug"][min(ns.verbose, 2)])
    return run_guarded(ns, ns.command_parser)


if __name__ == "__main__":
    sys.exit(main())
