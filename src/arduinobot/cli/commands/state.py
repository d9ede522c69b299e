"""`arduinobot fk`, `ik` and `check-state`: one state at a time, through the service or
in-process (--local)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from arduinobot.cli.argtypes import add_ground_arg, add_obstacle_arg, joint_values, numbers
from arduinobot.cli.commands.scene import add_scene_arg
from arduinobot.cli.common import (
    EXIT_FAIL,
    EXIT_OK,
    Service,
    add_service_args,
    connect,
    joints_by_name,
)
from arduinobot.client.replies import CheckReply, FkReply, IkReply

if TYPE_CHECKING:
    from arduinobot.contract.wire import Kind

_JOINTS_HELP = ("every actuated joint's value in the model's order (`arduinobot info` "
                "lists them), or name=value,... [rad]")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fk", help="forward kinematics: link poses and tcp of a joint state",
                       description="Print the world pose of each link (or --link ones), "
                       "the tcp position and the pose of each object the kept scene carries "
                       "for a joint state (missing joints are 0).",
                       epilog="example:\n  arduinobot fk --joints 0.5,0.3,-0.4 --link "
                       "claw_support")
    p.add_argument("--joints", metavar="Q", type=joint_values, help=_JOINTS_HELP)
    p.add_argument("--link", action="append", metavar="LINK", help="a link to report, "
                   "repeatable (default all)")
    _add_common(p, cmd_fk)

    p = sub.add_parser("ik", help="position inverse kinematics of the tcp",
                       description="Print every joint solution (branch) within the joint "
                       "limits that puts the tcp at a position [m]; exits 1 with "
                       "GOAL_OUT_OF_REACH when there is none.",
                       epilog="example:\n  arduinobot ik --position 0,1.0,1.2")
    p.add_argument("--position", required=True, metavar="X,Y,Z", type=numbers(3))
    _add_common(p, cmd_ik)

    p = sub.add_parser(
        "check-state", help="is a joint state collision-free? (not the model checker)",
        description="Check one joint STATE for validity: every colliding pair (self and "
        "obstacles) and the clearance to the closest pair. Exits 1 if it collides. Not to "
        "be confused with `arduinobot check`, which checks a MODEL file (URDF/xacro) for "
        "errors and simulation readiness.",
        epilog="example:\n  arduinobot check-state --joints 0,0.8,0.6 --obstacle "
        "box:table:1,1,0.1@0,1,0.5")
    p.add_argument("--joints", metavar="Q", type=joint_values, help=_JOINTS_HELP)
    add_obstacle_arg(p)
    add_ground_arg(p)
    p.add_argument("--padding", type=float, metavar="M", help="safety margin [m]")
    _add_common(p, cmd_check_state)
    add_scene_arg(p)


def _add_common(p: argparse.ArgumentParser, fn: Callable[[argparse.Namespace], int]) -> None:
    p.add_argument("--json", action="store_true", help="print the reply as JSON")
    add_service_args(p)
    p.set_defaults(func=fn)


def _ask(ns: argparse.Namespace, kind: Kind, req: dict[str, Any], *,
         with_joints: bool = True) -> dict[str, Any]:
    """The reply to ``req`` (with ``joints`` from --joints: positional values follow every
    actuated joint's order), printed as JSON with --json."""
    with connect(ns) as service:
        if with_joints:
            req = {"joints": _joints(ns, service), **req}
        body = service.request(kind, req)
    if ns.json:
        print(json.dumps(body, indent=1))
    return body


def _joints(ns: argparse.Namespace, service: Service) -> dict[str, float]:
    if not ns.joints:
        return {}
    return joints_by_name(service.description(), ns.joints, group="all", flag="--joints")


def _values(joints: Mapping[str, float]) -> str:
    return ", ".join(f"{k}={v:+.4f}" for k, v in joints.items())


def _xyz(v: tuple[float, ...]) -> str:
    return " ".join(f"{x:+.4f}" for x in v)


def cmd_fk(ns: argparse.Namespace) -> int:
    res = FkReply.parse(_ask(ns, "fk", {"links": ns.link} if ns.link else {}))
    if ns.json:
        return EXIT_OK
    print(f"joints: {_values(res.joints)}")
    w = max([20, *(len(n) + 1 for n in (*res.links, *res.carried))])  # long names
    for link, pose in res.links.items():
        print(f"{link:<{w}} xyz ({_xyz(pose.xyz)}) m  rpy ({_xyz(pose.rpy)}) rad")
    if res.tcp is not None:
        print(f"{'tcp':<{w}} xyz ({_xyz(res.tcp)}) m")
    for oid, pose in res.carried.items():  # the kept scene's carried objects
        print(f"{oid:<{w}} xyz ({_xyz(pose.xyz)}) m  rpy ({_xyz(pose.rpy)}) rad  "
              f"{'fixed to' if pose.fixed else 'carried by'} {pose.link}")
    return EXIT_OK


def cmd_ik(ns: argparse.Namespace) -> int:
    res = IkReply.parse(_ask(ns, "ik", {"position": ns.position}, with_joints=False))
    if not ns.json:
        for s in res.solutions:
            print(f"{s.branch:<20} {_values(s.joints)}")
    return EXIT_OK


def cmd_check_state(ns: argparse.Namespace) -> int:
    req: dict[str, Any] = {}
    if ns.obstacle:
        req["obstacles"] = ns.obstacle
    if ns.padding is not None:
        req["padding"] = ns.padding
    if not ns.ground:
        req["ground"] = False
    res = CheckReply.parse(_ask(ns, "check", req))
    if not ns.json:
        print(f"{'VALID (collision-free)' if res.valid else 'IN COLLISION'}: "
              f"{_values(res.joints)}")
        for a, b in res.pairs:
            print(f"  colliding: {a} / {b}")
        if res.hint:
            print(f"  {res.hint}")
        if res.clearance is not None and res.valid:
            print(f"  clearance {res.clearance:.4f} m between {' / '.join(res.closest or ())}")
    return EXIT_OK if res.valid else EXIT_FAIL
