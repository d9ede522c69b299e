"""`arduinobot check`, `urdf` and `info`: look at a model without ROS."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from arduinobot.cli.common import EXIT_FAIL, EXIT_OK, add_model_args, load_from_args, model_options
from arduinobot.description import Description, build_package_index
from arduinobot.description.loader import model_path, read_model

if TYPE_CHECKING:
    from arduinobot.description.checks import CheckReport


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check", help="check a URDF/xacro for errors and simulation readiness",
        description="Check a model as check_urdf does (one root, a tree, names resolve), "
        "then for simulation readiness (visual, collision and inertial on every link; "
        "mass > 0; physical inertia; meshes resolve, load and are watertight; sane limits; "
        "mimic targets; non-zero axes), then for plausibility (inertia against the "
        "mesh). Prints PASS/WARN/FAIL lines; exits 1 on any FAIL.",
        epilog="examples:\n  arduinobot check\n  arduinobot check my_robot.urdf.xacro "
        "--package-dir ~/ws/src/my_robot_description\n  arduinobot check --json")
    add_model_args(p)
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("urdf", help="print the expanded URDF",
                       description="Expand a xacro file in-process (no ROS needed) and print "
                       "the URDF; a plain URDF is printed as is.",
                       epilog="example:\n  arduinobot urdf --arg prefix=left_ > robot.urdf")
    add_model_args(p)
    p.set_defaults(func=cmd_urdf)

    p = sub.add_parser("info", help="print the kinematic tree with joint types, axes and limits",
                       description="Print the kinematic tree of a model: each link under its "
                       "parent, with the joint's type, axis, limits and mimic; then the "
                       "actuated joints and the SRDF's groups and named states; then the "
                       "limits the planner applies (full -> at the default scaling) and where "
                       "each came from (URDF, joint_limits.yaml, default rule, scaling); for "
                       "the shipped model, what its size means for the printed arm.",
                       formatter_class=argparse.HelpFormatter)  # no examples: wrapped
    add_model_args(p)
    p.set_defaults(func=cmd_info)


def cmd_check(ns: argparse.Namespace) -> int:
    from arduinobot.description.checks import check_model  # trimesh: only for this command

    report = check_model(ns.file, **model_options(ns))
    if not report.failed:
        report = _with_limit_findings(report, ns)
    if ns.json:
        print(json.dumps(report.to_json(), indent=2))
    else:
        print(f"checking {report.source}")
        for f in report.findings:
            print(f.line())
        print(f"{report.count('PASS')} passed, {report.count('WARN')} warnings, "
              f"{report.count('FAIL')} failed")
    return EXIT_FAIL if report.failed else EXIT_OK


def _with_limit_findings(report: CheckReport, ns: argparse.Namespace) -> CheckReport:
    """``report`` with what the planner's limits say of the model: a derived
    acceleration capped at what a servo can do (a WARN naming the figure), or no limits
    at all (a FAIL: planning refuses the model)."""
    from arduinobot.contract.errors import LimitsError
    from arduinobot.description.checks import Finding
    from arduinobot.planner.kinematics.limits import SERVO_ACCELERATION_CAP, JointLimits
    logging.getLogger("arduinobot.planner.kinematics.limits").setLevel(logging.ERROR)
    try:
        lim = JointLimits.from_description(load_from_args(ns))
    except LimitsError as e:
        return replace(report, findings=(*report.findings, Finding(
            "FAIL", "limits", f"{e.joint}.{e.limit}", e.message)))
    capped = {k.split(".")[0]: v.split("max M_ii(q) over ")[1].split(" seeded samples, ")[1]
              for k, v in lim.sources.items() if "capped at" in v}
    extra = [Finding("WARN", "limits.acceleration", joint,
                     f"derived {why}; set max_acceleration in joint_limits.yaml to the "
                     "servo's figure", {"cap": SERVO_ACCELERATION_CAP})
             for joint, why in capped.items()]
    return replace(report, findings=(*report.findings, *extra)) if extra else report


def cmd_urdf(ns: argparse.Namespace) -> int:
    packages = build_package_index(ns.package_dir, model=model_path(ns.file))
    text, _, warnings = read_model(ns.file, args=dict(ns.arg), packages=packages)
    for w in (*packages.warnings, *warnings):  # stdout is the URDF
        print(f"warning: {w}", file=sys.stderr)
    sys.stdout.write(text)
    return EXIT_OK


def _fmt(v: float | None) -> str:
    if v is None or not np.isfinite(v):
        return "-inf" if v is None or v < 0 else "inf"
    return f"{v:+.4f}"


def limits_lines(d: Description) -> list[str]:
    """The planner's limits per actuated joint, full and as applied at the default
    scaling (what a request without scaling gets), and where each came from."""
    from arduinobot.planner.kinematics.applied_limits import applied_limits
    lim = applied_limits(d, d.robot.actuated_joints)
    scaled = lim.velocity_scaling != 1.0 or lim.acceleration_scaling != 1.0
    w = max(12, *(len(j) + 2 for j in lim.joints))  # long joint names keep the columns
    out = ["limits" + (" (full -> applied at the default scaling):" if scaled else ":"),
           f"  {'joint':<{w}}{'position [rad]':<22}{'velocity':<18}{'acceleration':<20}"
           f"{'jerk':<20}effort"]

    def fig(kind: str, i: int) -> str:
        full, applied = lim.full[kind][i], lim.applied(kind)[i]
        return f"{full:.4g}" if full == applied else f"{full:.4g} -> {applied:.4g}"
    for i, j in enumerate(lim.joints):
        pos = f"[{_fmt(lim.full['lower'][i])}, {_fmt(lim.full['upper'][i])}]"
        out.append(f"  {j:<{w}}{pos:<22}{fig('velocity', i):<18}{fig('acceleration', i):<20}"
                   f"{fig('jerk', i):<20}{fig('effort', i)}")
    out.append("limits from:")
    out.extend(lim.lines())
    return out


class _Hold(logging.Handler):
    def __init__(self) -> None:
        super().__init__()
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def _load_printing_warnings_once(ns: argparse.Namespace) -> Description:
    """The model, with the loader's log replayed except the warnings ``info`` prints
    itself (the log showed each of them a second time, on stderr)."""
    log, hold = logging.getLogger("arduinobot.description"), _Hold()
    log.addHandler(hold)
    propagate, log.propagate = log.propagate, False
    d = None
    try:
        d = load_from_args(ns)
        return d
    finally:
        log.removeHandler(hold)
        log.propagate = propagate
        printed = set(d.warnings) if d is not None else set()
        for rec in hold.records:
            if rec.getMessage() not in printed:
                logging.getLogger(rec.name).handle(rec)


def cmd_info(ns: argparse.Namespace) -> int:
    d = _load_printing_warnings_once(ns)
    r = d.robot
    print(f"robot '{r.name}' from {r.source}")
    print(f"links {len(r.links)}, joints {len(r.joints)}, actuated {', '.join(r.actuated_joints)}")

    def walk(link: str, depth: int) -> None:
        for j in r.child_joints[link]:
            desc = f"{j.type}"
            if j.movable:
                desc += f" axis ({' '.join(f'{a:g}' for a in j.axis)})"
            if j.limit is not None and j.movable:
                desc += (f" [{_fmt(j.limit.lower)}, {_fmt(j.limit.upper)}] rad"
                         f" effort {j.limit.effort:g} velocity {j.limit.velocity:g}")
            if j.mimic is not None:
                desc += f" mimic {j.mimic.multiplier:g}*{j.mimic.joint}+{j.mimic.offset:g}"
            xyz = " ".join(f"{v:g}" for v in j.origin.xyz)
            print(f"{'  ' * depth}└─ {j.child}  via {j.name}: {desc}; origin xyz ({xyz})")
            walk(j.child, depth + 1)

    print(r.root)
    walk(r.root, 0)
    for line in d.config.lines():
        print(line)
    if d.srdf is not None:
        for g in d.srdf.groups.values():
            print(f"group {g.name}: {', '.join(g.joints)} (tip {g.tip_link})")
        for s in d.srdf.states:
            vals = ", ".join(f"{k}={v:g}" for k, v in s.values.items())
            print(f"named state {s.name} ({s.group}): {vals}")
    for name, joints in d.derived.items():
        print(f"group {name}: {', '.join(joints)} (no SRDF: derived from the tool point)")
    print(f"default group: {d.default_group()}")
    if d.tcp is not None:
        turned = f" rpy {d.tcp.rpy}" if any(d.tcp.rpy) else ""
        print(f"tcp: {d.tcp.xyz}{turned} in {d.tcp.parent_link} [{d.tcp.source}]")
    print(f"default scaling: velocity x{d.default_velocity_scaling:g}, acceleration "
          f"x{d.default_acceleration_scaling:g}")
    for line in limits_lines(d):
        print(line)
    if d.size_note is not None:
        print(f"size: {d.size_note}")
    for w in d.warnings:
        print(f"warning: {w}")
    return EXIT_OK
