"""The `arduinobot` command: one entry point, one subcommand per job."""

from __future__ import annotations

import argparse
import difflib
import inspect
import logging
import os
import re
import sys
from collections.abc import Iterable, Sequence
from typing import Any, NoReturn, TypeVar, overload

from arduinobot.cli.argtypes import FileProblem
from arduinobot.cli.commands import execute as cmd_execute
from arduinobot.cli.commands import model as cmd_model
from arduinobot.cli.commands import plan as cmd_plan
from arduinobot.cli.commands import scene as cmd_scene
from arduinobot.cli.commands import serve as cmd_serve
from arduinobot.cli.commands import srdf as cmd_srdf
from arduinobot.cli.commands import state as cmd_state
from arduinobot.cli.commands import task as cmd_task
from arduinobot.cli.commands import view as cmd_view
from arduinobot.cli.common import run_guarded
from arduinobot.cli.model_log import LOGGED_BY, PRINTED_BY, ModelWarnings

# Commands that run OMPL in this process (the second set with --local only), whose own log
# follows -v (quiet by default); a remote plan must not import OMPL (~1 s).
# (not serve: its workers plan and set OMPL's level themselves, src/arduinobot/service/process/zygote.py; the
# serving process never imports the planner)
_OMPL_ALWAYS, _OMPL_LOCAL = {"srdf", "view", "task"}, {"plan", "ik", "execute"}
_COMMANDS = [cmd_model, cmd_serve, cmd_srdf, cmd_view, cmd_plan, cmd_state, cmd_execute,
             cmd_scene, cmd_task]

#: what a value that starts with '-' but is no option looks like: a number, or a list of
#: them ('-1.14,-0.6,-0.07', '-.5'). The pattern of our Python's argparse (3.11) is one
#: number only, so `--goal -1.14,-0.6,-0.07` read the list as an unknown option and
#: failed with "expected one argument"; later CPython widened it to this same prefix.
NEGATIVE_VALUE = re.compile(r"-\.?\d")
#: argparse's own "maybe you meant" for a mistyped choice (a command, --profile's value)
_HAS_SUGGEST = "suggest_on_error" in inspect.signature(argparse.ArgumentParser).parameters
_N = TypeVar("_N")  # a namespace object given to parse_args


class CommandParser(argparse.ArgumentParser):
    """argparse for what users type: a value flag takes a negative first value
    (``--start -0.4,0.3,0``) in every command, and a mistyped command, choice or flag
    is answered with its closest match (``maybe you meant 'plan'?``), under the usage
    of the command it was typed for."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        if _HAS_SUGGEST:
            kwargs.setdefault("suggest_on_error", True)
        super().__init__(*args, **kwargs)
        # no option of ours looks like a number, so every such token is a value
        self._negative_number_matcher = NEGATIVE_VALUE

    # argparse's own overloads (a namespace given comes back, with its type)
    @overload
    def parse_args(self, args: Iterable[str] | None = None,
                   namespace: None = None) -> argparse.Namespace: ...
    @overload
    def parse_args(self, args: Iterable[str] | None, namespace: _N) -> _N: ...
    @overload
    def parse_args(self, *, namespace: _N) -> _N: ...

    def parse_args(self, args: Iterable[str] | None = None, namespace: Any = None) -> Any:
        ns, extras = self.parse_known_args(None if args is None else list(args), namespace)
        if extras:  # argparse would blame the top-level parser; blame the command's
            parser: CommandParser = getattr(ns, "command_parser", self)
            parser.unrecognized(extras)
        return ns

    def unrecognized(self, extras: Sequence[str]) -> NoReturn:
        """Exit 2 naming ``extras``, with the closest option for a mistyped flag."""
        options = [o for a in self._actions for o in a.option_strings]
        hints = []
        for arg in extras:
            flag = arg.split("=", 1)[0]
            if flag.startswith("-") and not NEGATIVE_VALUE.match(flag):
                close = difflib.get_close_matches(flag, options, n=1, cutoff=0.6)
                if close:
                    hints.append(f"maybe you meant {close[0]} (not {flag})?")
        self.error("; ".join([f"unrecognized arguments: {' '.join(extras)}", *hints]))

    def _get_value(self, action: argparse.Action, arg_string: str) -> Any:
        # a file given as a typed value (--request REQ.json) that cannot be read: one
        # line naming it, as run_guarded says a FileProblem, not the usage
        try:
            return super()._get_value(action, arg_string)
        except FileProblem as e:
            name = argparse._get_action_name(action)  # as argparse names it: --request
            self.exit(2, f"{self.prog}: error: argument {name}: {e}\n")

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        if _HAS_SUGGEST or action.choices is None or value in action.choices:
            return super()._check_value(action, value)
        # the wording of Python 3.14's suggest_on_error
        close = difflib.get_close_matches(str(value), [str(c) for c in action.choices], n=1)
        choices = ", ".join(map(repr, action.choices))
        maybe = f", maybe you meant {close[0]!r}?" if close else ""
        raise argparse.ArgumentError(action, f"invalid choice: {value!r}{maybe} "
                                     f"(choose from {choices})")


class _RawCommandParser(CommandParser):
    """A command's parser: its description and examples keep their line breaks."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    p = CommandParser(
        prog="arduinobot",
        description="Motion planning for the arduinobot arm (and your own URDF): load and "
        "check models without ROS, plan collision-free paths, time them within the "
        "motors' limits, and serve it all over Zenoh.",
        epilog="Every command that reads a model takes FILE (URDF or xacro; default: the "
        "shipped arduinobot) and --package-dir DIR, and honours ROS_PACKAGE_PATH and "
        "AMENT_PREFIX_PATH. 'arduinobot COMMAND --help' explains each command.")
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="log more (-v info, -vv debug) to stderr")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True,
                           parser_class=_RawCommandParser)
    for mod in _COMMANDS:
        mod.register(sub)
    for sp in sub.choices.values():  # a usage error names its command, as argparse's do
        sp.set_defaults(command_parser=sp)
    return p


#: the exit code when stdout's reader went away (128 + SIGPIPE, as a C tool ends)
EXIT_BROKEN_PIPE = 141


def main(argv: list[str] | None = None) -> int:
    ns = build_parser().parse_args(argv)
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(ns.verbose, 2)]
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        stream=sys.stderr)
    held = None if ns.command in LOGGED_BY else ModelWarnings(show=ns.verbose > 0)
    handlers = list(logging.getLogger().handlers)
    if held is not None:
        for handler in handlers:
            handler.addFilter(held)
    if ns.command in _OMPL_ALWAYS or (ns.command in _OMPL_LOCAL and ns.local):
        from arduinobot.planner.planning.pathfinding.search import set_ompl_log_level
        set_ompl_log_level(["none", "info", "debug"][min(ns.verbose, 2)])
    try:
        try:
            rc = run_guarded(ns, ns.command_parser)
        finally:
            said = None
            if held is not None:
                for handler in handlers:  # main() may run again in this process (tests)
                    handler.removeFilter(held)
                said = None if ns.command in PRINTED_BY else held.summary(ns.command)
            if said:
                print(said, file=sys.stderr)
        sys.stdout.flush()  # here, not at exit, so a closed pipe is caught below
    except BrokenPipeError:
        # `arduinobot fk | head`: the reader is gone, which is no error of ours. Point
        # stdout at /dev/null so the interpreter's own flush at exit stays quiet, and end
        # as a C tool killed by SIGPIPE would (128 + 13), for `set -o pipefail`.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    return rc


if __name__ == "__main__":
    sys.exit(main())
