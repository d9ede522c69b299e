"""`arduinobot plan`: plan a motion through the service (or in-process with --local)."""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from arduinobot.cli.argtypes import (
    JointValues,
    UsageError,
    add_ground_arg,
    add_obstacle_arg,
    joint_values,
    json_object,
    numbers,
)
from arduinobot.cli.commands.scene import add_scene_arg
from arduinobot.cli.common import (
    EXIT_OK,
    add_service_args,
    connect,
    joint_order,
    joints_by_name,
    planned_by,
    wrote,
)
from arduinobot.client.replies import PlanReply
from arduinobot.planner.kinematics.applied_limits import AppliedLimits


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plan", help="plan a collision-free, timed motion (through the service or --local)",
        description="Plan a motion to a goal and print a summary: duration, per-joint peak "
        "velocity, acceleration and effort against their limits, and the time each stage "
        "took. Sends a v1 request to `arduinobot serve` (start one first), or plans "
        "in-process with --local exactly as the service would.",
        epilog="examples:\n  arduinobot plan --goal -1.14,-0.6,-0.07\n"
        "  arduinobot plan --start 0.3,0.4,-0.3 --offset 0,0,-0.05\n"
        "  arduinobot plan --group gripper --goal -0.7,0.7\n"
        "  arduinobot plan --named reach_left --start 0.2,0,0 --json traj.json\n"
        "  arduinobot plan --position 0,1.0,1.2 --obstacle box:table:1,1,0.1@0,1,0.5\n"
        "  arduinobot plan --request req.json --local --plot traj.png")
    goal = p.add_mutually_exclusive_group()
    goal.add_argument("--goal", metavar="Q", type=joint_values, help="joint goal: a value "
                      "for each of the group's joints in the model's order (`arduinobot "
                      "info` lists them; a mimic's value may follow its leader's and must "
                      "agree with it: --group gripper --goal -0.7,0.7), or name=value,... "
                      "for some (the others keep their start value)")
    goal.add_argument("--named", metavar="NAME", help="a named SRDF state (home, ...)")
    goal.add_argument("--position", metavar="X,Y,Z", type=numbers(3),
                      help="a tcp position [m]")
    goal.add_argument("--line", metavar="X,Y,Z", type=numbers(3),
                      help="a straight-line tcp move (Pilz LIN) to this position [m]")
    goal.add_argument("--offset", metavar="DX,DY,DZ", type=numbers(3),
                      help="a straight-line tcp move by this offset [m] (see --frame)")
    goal.add_argument("--request", metavar="REQ.json", type=json_object, help="a whole v1 request from a file "
                      "(options given here override its fields)")
    p.add_argument("--frame", choices=("world", "tcp"), help="the frame of --offset: world "
                   "(default) or the tool frame at the start")
    p.add_argument("--tolerance", type=float, metavar="M", help="with --position: the tcp "
                   "may end anywhere within this radius [m] where the exact point is out of "
                   "reach or collides")
    p.add_argument("--start", metavar="Q", type=joint_values, help="start: every actuated joint's value in the "
                   "model's order or name=value,...; "
                   "default all 0")
    add_obstacle_arg(p)
    p.add_argument("--group", metavar="NAME", help="a planning group of the model's SRDF, "
                   "or all (default: a named goal's own group, else arm, else the first)")
    p.add_argument("--planner", metavar="NAME", help="an OMPL planner (default RRTConnect)")
    p.add_argument("--planning-time", type=float, metavar="S")
    p.add_argument("--velocity-scaling", type=float, metavar="F")
    p.add_argument("--acceleration-scaling", type=float, metavar="F")
    p.add_argument("--profile", choices=("jerk_limited", "time_optimal"))
    p.add_argument("--sample-rate", type=float, metavar="HZ")
    p.add_argument("--seed", type=int)
    add_ground_arg(p)
    out = p.add_argument_group("output")
    out.add_argument("--json", metavar="OUT", help="write the whole response as JSON "
                     "('-' for stdout)")
    out.add_argument("--csv", metavar="OUT", help="write the samples as CSV")
    out.add_argument("--plot", metavar="OUT.png", help="plot positions, velocities, "
                     "accelerations and efforts with their limits (needs matplotlib); "
                     "with --simulate, commanded vs simulated positions")
    out.add_argument("--simulate", action="store_true", help="replay the trajectory on "
                     "the MuJoCo twin (needs mujoco): tracking error, peak actuator force "
                     "vs the effort limit, contacts")
    add_service_args(p)
    add_scene_arg(p)
    p.set_defaults(func=cmd_plan)


def build_request(ns: argparse.Namespace, robot: Mapping[str, Any]) -> dict[str, Any]:
    """The v1 plan request of the options (and --request's file); ``robot``, the
    service's ``<prefix>/description``, gives positional joint values their joints."""
    req: dict[str, Any] = dict(ns.request or {})
    group = ns.group or req.get("group")
    if ns.goal is not None:
        req["goal"] = {"joints": goal_joints(robot, ns.goal, group=group)}
    elif ns.named:
        req["goal"] = {"named": ns.named}
    elif ns.position:
        req["goal"] = {"position": ns.position}
    elif ns.line:
        req["goal"] = {"line": {"position": ns.line}}
    elif ns.offset:
        req["goal"] = {"line": {"offset": ns.offset, "frame": ns.frame or "world"}}
    elif "goal" not in req:
        raise UsageError("give a goal: --goal, --named, --position, --line, --offset or "
                         "--request")
    if ns.frame is not None and not ns.offset:
        raise UsageError("--frame applies to --offset")
    if ns.tolerance is not None:
        if not ns.position:
            raise UsageError("--tolerance applies to --position")
        req["goal"]["tolerance"] = ns.tolerance
    if ns.start is not None:
        req["start"] = joints_by_name(robot, ns.start, group="all", flag="--start")
    if ns.obstacle:
        req["obstacles"] = [*req.get("obstacles", []), *ns.obstacle]
    if not ns.ground:
        req["ground"] = False
    for key in ("group", "planner", "planning_time", "velocity_scaling",
                "acceleration_scaling", "profile", "sample_rate", "seed"):
        v = getattr(ns, key)
        if v is not None:
            req[key] = v
    return req


def goal_joints(robot: Mapping[str, Any], values: JointValues, *, group: str | None
                ) -> dict[str, float]:
    """``--goal``'s joints by name. Positional values must give every joint of the group
    (a mimic's may be left out): fewer is a usage error, not a goal that silently keeps
    the rest; by name, the joints not named keep their start value, which is said on
    stderr (stdout may be the reply, ``--json -``).

    Raises:
        UsageError: fewer positional values than the group's joints, or what
            :func:`joints_by_name` refuses.
    """
    name = group or robot["default_group"]
    mimics = robot.get("mimic_joints", {})
    moving = [j for j in joint_order(robot, group) if j not in mimics]
    if not isinstance(values, dict) and len(values) < len(moving):
        raise UsageError(
            f"--goal gives {len(values)} value(s) for the {len(moving)} joints of group "
            f"'{name}' ({', '.join(moving)}): give all {len(moving)}, or name=value for "
            "the joints to move (the others then keep their start value)")
    joints = joints_by_name(robot, values, group=group, flag="--goal")
    led = {mimics[j]["leader"] for j in joints if j in mimics}  # the service's to refuse
    kept = [j for j in moving if j not in joints and j not in led]
    if kept:
        one = len(kept) == 1
        print(f"note: --goal moves {', '.join(joints)}; {', '.join(kept)} of group "
              f"'{name}' keep{'s its' if one else ' their'} start value", file=sys.stderr)
    return joints


def cmd_plan(ns: argparse.Namespace) -> int:
    if ns.plot and importlib.util.find_spec("matplotlib") is None:  # before planning
        raise UsageError("--plot needs matplotlib (pip install matplotlib)")
    with connect(ns) as service:
        robot = service.description()
        req = build_request(ns, robot)
        res = PlanReply.parse(service.request("plan", req))
    limits = AppliedLimits.from_description_reply(robot, res.joint_names, request=req)
    data_out = ns.json == "-"  # stdout is the reply: what is said goes to stderr
    samples = f"{len(res.times)} samples"
    if ns.json:
        text = json.dumps(res.raw, indent=1)
        if data_out:
            sys.stdout.write(text + "\n")
        else:
            Path(ns.json).write_text(text)
            wrote(ns.json, samples)
    if ns.csv:
        Path(ns.csv).write_text(res.to_csv())
        wrote(ns.csv, samples, stderr=data_out)
    if ns.plot and not ns.simulate:
        plot_trajectory(res, limits, ns.plot)
        wrote(ns.plot, f"plot of {samples}", stderr=data_out)
    if not data_out:
        print(f"robot '{robot['robot']}', planned {planned_by(ns)}")
        print(summary(res, limits))
    if ns.simulate:
        from arduinobot.cli.simulate import simulate_command
        return simulate_command(ns, res, req, robot)
    return EXIT_OK


def summary(res: PlanReply, limits: AppliedLimits) -> str:
    """Duration, per-joint peaks against the limits the plan was held to (scaled), where
    those came from, stage timings."""
    lines = [(f"trajectory: {len(res.times)} points, duration {res.duration:.3f} s, "
              f"{len(res.path)} waypoints, planner {res.planner}, request {res.request_id}")]
    # the name column as wide as the longest name (SO-101: 'shoulder_pan', 'wrist_roll')
    w = max([10, *(len(j) + 2 for j in res.joint_names)])
    lines.append(f"{'joint':<{w}}{'|v| peak':>10}{'limit':>8}{'|a| peak':>10}{'limit':>8}"
                 f"{'|j| peak':>10}{'limit':>9}{'|effort|':>10}{'limit':>8}")
    n = len(res.joint_names)
    peaks = {k: np.abs(getattr(res, k)).max(axis=0) if len(res.times) else np.zeros(n)
             for k in ("velocities", "accelerations", "efforts")}
    # jerk as the verifier measures it: finite differences of the sampled accelerations
    dt = np.diff(res.times)[:, None]
    jerk = np.abs(np.diff(res.accelerations, axis=0) / np.where(dt > 0, dt, np.inf))
    peaks["jerk"] = jerk.max(axis=0) if len(jerk) else np.zeros(n)
    applied = {k: limits.applied(k) for k in ("velocity", "acceleration", "jerk", "effort")}

    def lim(kind: str, i: int, width: int = 8) -> str:
        v = applied[kind][i]
        return f"{v:{width}.2f}" if np.isfinite(v) else f"{'-':>{width}}"
    for i, j in enumerate(res.joint_names):
        lines.append(f"{j:<{w}}{peaks['velocities'][i]:10.3f}{lim('velocity', i)}"
                     f"{peaks['accelerations'][i]:10.3f}{lim('acceleration', i)}"
                     f"{peaks['jerk'][i]:10.2f}{lim('jerk', i, 9)}"
                     f"{peaks['efforts'][i]:10.3f}{lim('effort', i)}")
    lines.append("limits applied (full figure from, x scaling):")
    lines.extend(limits.lines())
    v = res.verification
    gap = "not measured" if v.min_clearance is None else f"{1000 * v.min_clearance:.1f} mm"
    if v.min_clearance is not None and v.closest_pair:
        gap += f" ({v.closest_pair[0]} to {v.closest_pair[1]})"
    lines.append(f"verification: {'ok' if v.ok else 'FAILED'}; closest to its limit: "
                 f"{v.worst_quantity} at {100 * v.worst_ratio:.1f}% (of the scaled limits); "
                 f"min clearance {gap}")
    if res.line is not None:
        ln, peak = res.line, res.line.get("peak", {})
        cart = ln.get("limits", {})
        lines.append(f"line: {ln['length']:.4f} m, largest deviation "
                     f"{1000 * ln['max_deviation']:.3f} mm; tcp peak "
                     f"{peak.get('velocity', 0):.3f} m/s (limit {cart.get('max_trans_vel', 0):.3g}),"
                     f" {peak.get('acceleration', 0):.3f} m/s^2 (limits "
                     f"{cart.get('max_trans_acc', 0):.3g} / {cart.get('max_trans_dec', 0):.3g}), "
                     f"{peak.get('angular_velocity', 0):.3f} rad/s (limit "
                     f"{cart.get('max_rot_vel', 0):.3g}); limits from {cart.get('source', '?')}")
    if res.reached is not None and "position" in res.reached:
        r, resid = res.reached, res.reached.get("residuals", {})
        parts = [f"tcp {[round(v, 4) for v in r['position']]} m, "
                 f"rpy {[round(v, 4) for v in r['rpy']]} rad"]
        if "position" in resid:
            parts.append(f"{1000 * resid['position']:.3f} mm from the goal")
        if "orientation" in resid:
            parts.append(f"orientation off by {[round(v, 4) for v in resid['orientation']]} rad")
        if resid.get("joints"):
            parts.append("joints off by " + ", ".join(
                f"{k} {v:.2g}" for k, v in resid["joints"].items()))
        lines.append("reached: " + "; ".join(parts)
                     + ("" if r.get("within_tolerance", True) else " (OUTSIDE the tolerance)"))
    lines.append("timing: " + ", ".join(f"{k} {1000 * t:.1f} ms" for k, t in res.timing.items()))
    return "\n".join(lines)


def plot_trajectory(res: PlanReply, limits: AppliedLimits, out: str) -> None:
    """Positions, velocities, accelerations and efforts over time with their limits
    (dashed), one panel each (:mod:`viewer.plots`), saved to ``out``. Needs
    matplotlib (optional)."""
    from arduinobot.viewer.plots import limit_notes, limits_of, plot_figure, plot_panels
    from arduinobot.viewer.trajectory import PlaybackTrajectory
    traj = PlaybackTrajectory(res.joint_names, res.times, res.positions, res.velocities,
                              res.accelerations, res.efforts)
    panels = plot_panels(traj, limits_of(limits), notes=limit_notes(limits))
    fig = plot_figure(panels, title=f"{res.duration:.3f} s, {len(res.times)} samples "
                      "(dashed: the limits applied)", dpi=100)
    fig.savefig(out)
