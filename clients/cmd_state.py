"""`arduinobot fk`, `ik` and `check-state`: one state at a time, through the service or
in-process (--local)."""

from __future__ import annotations

import argparse
import json

from .cmd_plan import (
    add_service_args,
    floats,
    guarded,
    joint_map,
    joint_order,
    obstacle,
    run_request,
)
from .common import EXIT_FAIL, EXIT_OK


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fk", help="forward kinematics: link poses and tcp of a joint state",
                       description="Print the world pose of each link (or --link ones) and "
                       "the tcp position for a joint state (missing joints are 0).",
                       epilog="example:\n  arduinobot fk --joints 0.5,0.3,-0.4 --link "
                       "claw_support", formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--joints", default="", metavar="Q",
                   help="every actuated joint's value in the model's order "
                   "(`arduinobot model` lists them), or name=value,... [rad]")
    p.add_argument("--link", action="append", metavar="LINK", help="a link to report, "
                   "repeatable (default all)")
    p.add_argument("--json", action="store_true", help="print the reply as JSON")
    add_service_args(p)
    p.set_defaults(func=guarded(cmd_fk))

    p = sub.add_parser("ik", help="position inverse kinematics of the tcp",
                       description="Print every joint solution (branch) within the joint "
                       "limits that puts the tcp at a position [m]; exits 1 with "
                       "GOAL_OUT_OF_REACH when there is none.",
                       epilog="example:\n  arduinobot ik --position 0,1.0,1.2",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--position", required=True, metavar="X,Y,Z")
    p.add_argument("--json", action="store_true", help="print the reply as JSON")
    add_service_args(p)
    p.set_defaults(func=guarded(cmd_ik))

    p = sub.add_parser(
        "check-state", help="is a joint state collision-free? (not the model checker)",
        description="Check one joint STATE for validity: every colliding pair (self and "
        "obstacles) and the clearance to the closest pair. Exits 1 if it collides. Not to "
        "be confused with `arduinobot check`, which checks a MODEL file (URDF/xacro) for "
        "errors and simulation readiness.",
        epilog="example:\n  arduinobot check-state --joints 0,0.8,0.6 --obstacle "
        "box:table:1,1,0.1@0,1,0.5", formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--joints", default="", metavar="Q",
                   help="every actuated joint's value in the model's order "
                   "(`arduinobot model` lists them), or name=value,... [rad]")
    p.add_argument("--obstacle", action="append", default=[], metavar="SPEC",
                   help="box:ID:sx,sy,sz@x,y,z[@r,p,y], sphere:ID:r@x,y,z or "
                   "cylinder:ID:r,l@x,y,z; repeatable")
    p.add_argument("--padding", type=float, metavar="M", help="safety margin [m]")
    p.add_argument("--json", action="store_true", help="print the reply as JSON")
    add_service_args(p)
    p.set_defaults(func=guarded(cmd_check_state))


def _joints(ns: argparse.Namespace) -> dict[str, float]:
    text = ns.joints
    if not text:
        return {}
    return joint_map(text, () if "=" in text else joint_order(ns, "all"), "--joints")


def cmd_fk(ns: argparse.Namespace) -> int:
    req: dict = {"joints": _joints(ns)}
    if ns.link:
        req["links"] = ns.link
    body, _ = run_request(ns, "fk", req)
    if ns.json:
        print(json.dumps(body, indent=1))
        return EXIT_OK
    print("joints: " + ", ".join(f"{k}={v:+.4f}" for k, v in body["joints"].items()))
    for link, pose in body["links"].items():
        xyz = " ".join(f"{v:+.4f}" for v in pose["xyz"])
        rpy = " ".join(f"{v:+.4f}" for v in pose["rpy"])
        print(f"{link:<20} xyz ({xyz}) m  rpy ({rpy}) rad")
    if body.get("tcp") is not None:
        print(f"{'tcp':<20} xyz ({' '.join(f'{v:+.4f}' for v in body['tcp'])}) m")
    return EXIT_OK


def cmd_ik(ns: argparse.Namespace) -> int:
    body, _ = run_request(ns, "ik", {"position": floats(ns.position, "--position", 3)})
    if ns.json:
        print(json.dumps(body, indent=1))
        return EXIT_OK
    for s in body["solutions"]:
        print(f"{s['branch']:<20} " + ", ".join(f"{k}={v:+.4f}" for k, v in s["joints"].items()))
    return EXIT_OK


def cmd_check_state(ns: argparse.Namespace) -> int:
    req: dict = {"joints": _joints(ns)}
    if ns.obstacle:
        req["obstacles"] = [obstacle(o) for o in ns.obstacle]
    if ns.padding is not None:
        req["padding"] = ns.padding
    body, _ = run_request(ns, "check", req)
    if ns.json:
        print(json.dumps(body, indent=1))
    else:
        state = "VALID (collision-free)" if body["valid"] else "IN COLLISION"
        print(f"{state}: " + ", ".join(f"{k}={v:+.4f}" for k, v in body["joints"].items()))
        for a, b in body["pairs"]:
            print(f"  colliding: {a} / {b}")
        if body.get("clearance") is not None and body["valid"]:
            print(f"  clearance {body['clearance']:.4f} m between "
                  f"{' / '.join(body['closest'] or ())}")
    return EXIT_OK if body["valid"] else EXIT_FAIL
