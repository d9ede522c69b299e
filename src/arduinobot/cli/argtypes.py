"""The command line's values: argparse types (their errors: argparse's usage message,
``arduinobot <cmd>: error: argument --goal: ...``, exit 2), and :class:`UsageError` for
checks across flags or against the robot, which :func:`arduinobot.cli.common.run_guarded` turns
into the same message and exit code; :class:`FileProblem` for a file named on the command
line, said in one line without the usage."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.zconfig import check_prefix
from arduinobot.scene.shapes import kinds, shape_class

#: joint values as given: positional (in the model's order) or by name
JointValues = tuple[float, ...] | dict[str, float]

_FORMS = [f"{k}:ID:{c.cli_form}@x,y,z" for k in kinds()
          if (c := shape_class(k)).cli_form is not None]
_FORMS[0] += "[@r,p,y]"
_OBSTACLE_FORMS = ", ".join(_FORMS[:-1]) + " or " + _FORMS[-1]


class UsageError(Exception):
    """A command line that parses but does not make sense (flags that exclude each other,
    more joint values than joints); the message names the flag."""


class FileProblem(UsageError):
    """A file named on the command line is missing, unreadable or not what it should be:
    said in one line naming the file (exit 2), without the command's usage, which would
    bury it and has nothing to do with it."""


def file_problem(path: str | Path, e: Exception, what: str = "") -> FileProblem:
    """The :class:`FileProblem` of reading ``path`` (a ``what`` such as 'task file')
    failing with ``e``: the OS's words for a missing or unreadable file, the parser's for
    a bad one."""
    reason = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
    return FileProblem(f"cannot read {what + ' ' if what else ''}{path}: {reason}")


def _floats(text: str, n: int | None = None, what: str = "") -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{what}'{text}' must be comma-separated "
                                         "numbers") from None
    if n is not None and len(vals) != n:
        raise argparse.ArgumentTypeError(f"{what}'{text}' needs {n} numbers")
    return vals


def numbers(n: int) -> Callable[[str], list[float]]:
    """The type of a flag taking ``n`` comma-separated numbers (``--position 0,1,1.2``)."""
    def parse(text: str) -> list[float]:
        return _floats(text, n)
    return parse


def joint_values(text: str) -> JointValues:
    """``0.5,0.3,-0.4`` (positional: the joints' order comes later, from the model) or
    ``NAME=0.5,OTHER=-0.4``."""
    if "=" not in text:
        return tuple(_floats(text))
    out = {}
    for item in text.split(","):
        name, _, v = item.partition("=")
        if not name.strip():
            raise argparse.ArgumentTypeError(f"'{text}': '{item}' must be NAME=VALUE")
        out[name.strip()] = _floats(v, 1, f"{name.strip()}: ")[0]
    return out


@dataclass(frozen=True)
class Mimic:
    """A mimic joint's rule: its value is ``multiplier * leader + offset`` [rad]."""

    leader: str
    multiplier: float = 1.0
    offset: float = 0.0

    def follows(self, leader_value: float) -> float:
        return self.multiplier * leader_value + self.offset

    def rule(self, name: str) -> str:
        return f"{name} = {self.multiplier:g} * {self.leader} + {self.offset:g}"


#: how far a mimic's typed value may be from what its leader gives [rad] (what a user
#: types, '-0.7,0.7', is exact; a value copied with 6 decimals is within this)
MIMIC_TOLERANCE = 1e-6


def joint_map(values: JointValues, names: Sequence[str], flag: str, *,
              mimics: Mapping[str, Mimic] | None = None,
              all_joints: Sequence[str] = ()) -> dict[str, float]:
    """``values`` by joint name; positional ones follow ``names``, or, when there are more
    of them than ``names``, ``names`` with each joint's mimics right after it (as the
    SRDF and MoveIt list a gripper: ``joint_4, joint_5``). A mimic's value must agree
    with its leader's (``mimics``) and is then dropped: the service takes leaders only.

    Args:
        mimics: the robot's mimic joints by name (``<prefix>/description``'s
            ``mimic_joints``).
        all_joints: every actuated joint: named in the error when the values would fit
            them (``--group all``) and not ``names``.

    Raises:
        UsageError: more positional values than ``names`` and their mimics; a mimic's
            value that disagrees with its leader's (naming both).
    """
    mimics = mimics or {}
    if isinstance(values, dict):
        pairs = list(values.items())
    else:
        order = list(names)
        if len(values) > len(names):
            order = with_mimics(names, mimics)
        if len(values) > len(order):
            raise UsageError(_too_many(values, names, order, flag, mimics, all_joints))
        pairs = list(zip(order, values))
    given = dict(pairs)
    out = {}
    for name, v in pairs:
        m = mimics.get(name)
        if m is None or m.leader not in given:
            out[name] = v  # a mimic alone: the service names its leader
            continue
        expected = m.follows(given[m.leader])
        if abs(v - expected) > MIMIC_TOLERANCE:
            raise UsageError(f"{flag}: {name} is a mimic of {m.leader} ({m.rule(name)}): "
                             f"{m.leader}={given[m.leader]:g} gives {name}={expected:g}, "
                             f"not {v:g}; give {m.leader}'s value alone (or one that "
                             f"agrees)")
    return out


def with_mimics(names: Sequence[str], mimics: Mapping[str, Mimic]) -> list[str]:
    """``names`` with each joint's mimics right after it."""
    return [x for n in names for x in (n, *(k for k, m in mimics.items() if m.leader == n))]


def _too_many(values: Sequence[float], names: Sequence[str], order: Sequence[str], flag: str,
              mimics: Mapping[str, Mimic], all_joints: Sequence[str]) -> str:
    listed = ", ".join(names)
    extra = [n for n in order if n not in names]
    if extra:
        listed += f"; or with their mimics: {', '.join(order)}"
    msg = f"{flag}: {len(values)} values for {len(names)} joints ({listed})"
    every = list(all_joints)
    if every and list(names) != every and len(values) in (len(every),
                                                          len(with_mimics(every, mimics))):
        msg += f"; for every joint ({', '.join(every)}), add --group all"
    return msg


def obstacle(text: str) -> dict[str, Any]:
    """``box:ID:sx,sy,sz@x,y,z[@r,p,y]``, ``sphere:ID:r@...``, ``cylinder:ID:r,l@...`` (each
    shape with a numeric form, :attr:`arduinobot.scene.shapes.Shape.cli_form`) as the
    service's obstacle object (sizes and positions [m], rpy [rad])."""
    head, *poses = text.split("@")
    parts = head.split(":")
    if len(parts) != 3 or parts[0] not in kinds() or len(poses) > 2 \
            or (cls := shape_class(parts[0])).cli_form is None:
        raise argparse.ArgumentTypeError(f"'{text}' must be {_OBSTACLE_FORMS}")
    shape, oid, dims = parts
    o: dict[str, Any] = {"id": oid, "shape": shape}
    count = len((cls.cli_form or "").split(","))
    o.update(cls.json_of_numbers(_floats(dims, count, f"{','.join(cls.field_names())} ")))
    for key, pose in zip(("xyz", "rpy"), poses):
        o[key] = _floats(pose, 3, f"{key} ")
    return o


def json_object(path: str) -> dict[str, Any]:
    """The JSON object in the file ``path`` (a request: ``--request REQ.json``)."""
    try:
        data = json.loads(Path(path).read_text("utf-8"))
    except (OSError, ValueError) as e:
        raise file_problem(path, e) from None
    if not isinstance(data, dict):
        raise FileProblem(f"{path} must hold a JSON object")
    return data


def add_obstacle_arg(p: argparse.ArgumentParser) -> None:
    """--obstacle SPEC (repeatable), as plan and check-state take it."""
    p.add_argument("--obstacle", action="append", default=[], metavar="SPEC", type=obstacle,
                   help=f"{_OBSTACLE_FORMS}; repeatable")


def add_ground_arg(p: argparse.ArgumentParser) -> None:
    """--no-ground (``ns.ground`` False), as plan and check-state take it."""
    p.add_argument("--no-ground", dest="ground", action="store_false",
                   help="no ground: by default the plane the base stands on (z = 0 of the "
                   "model's root frame) is an obstacle 'ground' that no moving link or "
                   "carried object may touch (a goal or line under it is refused naming "
                   "it), and the twin's floor. Use this for an arm on a wall, a post or "
                   "the edge of a table that reaches below its base. An --obstacle with "
                   "the id 'ground' replaces ours instead")


def xacro_arg(text: str) -> tuple[str, str]:
    """``NAME=VALUE`` or ``NAME:=VALUE`` (``--arg``; the second is how ROS users type it)."""
    name, sep, value = text.partition("=")
    name = name.removesuffix(":")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"'{text}' must be NAME=VALUE or NAME:=VALUE")
    return name, value


def key_prefix(text: str) -> str:
    """A ``--prefix``: literal chunks only (:func:`arduinobot.contract.zconfig.check_prefix`)."""
    try:
        return check_prefix(text)
    except InvalidRequest as e:
        raise argparse.ArgumentTypeError(e.message) from None


def positive_int(text: str) -> int:
    n = int(text)  # a ValueError: argparse's "invalid positive_int value: 'x'"
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, not {n}")
    return n
