"""`arduinobot plan`: plan a motion through the service (or in-process with --local)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from .common import (
    EXIT_FAIL,
    EXIT_OK,
    add_connection_args,
    add_model_args,
    local_description,
    model_chosen,
)

EXIT_UNAVAILABLE = 3


# -- shared by the service commands (plan, fk, ik, check-state) -------------------------
def add_service_args(p: argparse.ArgumentParser) -> None:
    """--connect/--prefix/--timeout for the service, --local and the model for in-process."""
    g = p.add_argument_group("service (default) or in-process (--local)")
    add_connection_args(g, timeout_help="seconds to wait for the reply (default 60)",
                        local_help="run in this process, no service (the model: "
                        "FILE/--package-dir)")
    add_model_args(p)


def floats(text: str, what: str, n: int | None = None) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(f"arduinobot: error: {what} '{text}' must be comma-separated "
                         "numbers") from None
    if n is not None and len(vals) != n:
        raise SystemExit(f"arduinobot: error: {what} '{text}' needs {n} numbers")
    return vals


def joint_map(text: str, names: Sequence[str], what: str) -> dict[str, float]:
    """``0.5,0.3,-0.4`` (in ``names`` order) or ``NAME=0.5,OTHER=-0.4``."""
    if "=" in text:
        out = {}
        for item in text.split(","):
            name, _, v = item.partition("=")
            out[name.strip()] = floats(v, what, 1)[0]
        return out
    vals = floats(text, what)
    if len(vals) > len(names):
        raise SystemExit(f"arduinobot: error: {what} '{text}' has {len(vals)} values for "
                         f"{len(names)} joints ({', '.join(names)})")
    return dict(zip(names, vals))


def obstacle(text: str) -> dict[str, Any]:
    """``box:ID:sx,sy,sz@x,y,z[@r,p,y]``, ``sphere:ID:r@...``, ``cylinder:ID:r,l@...``."""
    head, *poses = text.split("@")
    parts = head.split(":")
    if len(parts) != 3 or parts[0] not in ("box", "sphere", "cylinder"):
        raise SystemExit(f"arduinobot: error: --obstacle '{text}' must be "
                         "box:ID:sx,sy,sz@x,y,z, sphere:ID:r@x,y,z or cylinder:ID:r,l@x,y,z")
    shape, oid, dims = parts
    o: dict[str, Any] = {"id": oid, "shape": shape}
    if shape == "box":
        o["size"] = floats(dims, "--obstacle size", 3)
    elif shape == "sphere":
        o["radius"] = floats(dims, "--obstacle radius", 1)[0]
    else:
        o["radius"], o["length"] = floats(dims, "--obstacle radius,length", 2)
    if poses:
        o["xyz"] = floats(poses[0], "--obstacle position", 3)
    if len(poses) > 1:
        o["rpy"] = floats(poses[1], "--obstacle rpy", 3)
    return o


def robot_joints(ns: argparse.Namespace) -> Mapping[str, Any]:
    """The planned-for robot's groups, default group and actuated joints
    (:meth:`description.Description.summary`): from the model with --local, else from
    the service's ``<prefix>/description``. Only asked for when positional joint values
    need the joints' order."""
    if ns.local:
        return local_description(ns).summary()
    from .client import PlannerClient
    with PlannerClient(ns.connect or ("tcp/127.0.0.1:7447",), prefix=ns.prefix,
                       timeout=ns.timeout, config_file=ns.config) as c:
        return c.description()


def joint_order(ns: argparse.Namespace, group: str | None) -> tuple[str, ...]:
    """The joints positional values follow: ``group``'s (the default group if None),
    or every actuated joint for ``all``."""
    info = robot_joints(ns)
    name = group or info["default_group"]
    groups = info["groups"]
    if name not in groups:
        raise SystemExit(f"arduinobot: error: --group '{name}' is not a group of this robot "
                         f"({', '.join(groups)})")
    return tuple(groups[name])


def run_request(ns: argparse.Namespace, kind: str, req: Mapping[str, Any]
                ) -> tuple[dict[str, Any], Mapping[str, Any] | None]:
    """Send ``req`` to the service, or with --local run it as a worker would (same
    parsing, same checks). Returns the reply body and the description's limits."""
    if ns.local:
        from service.local import LocalService
        local = LocalService(local_description(ns))
        return local.request(kind, req), local.limits()  # type: ignore[arg-type]
    if model_chosen(ns):
        raise SystemExit("arduinobot: error: FILE, --package-dir, --arg, --moveit-config, "
                         "--srdf and --joint-limits choose the model for --local; the "
                         "service plans for the model it serves")
    from .client import PlannerClient
    with PlannerClient(ns.connect or ("tcp/127.0.0.1:7447",), prefix=ns.prefix,
                       timeout=ns.timeout, config_file=ns.config) as c:
        body = c.request(kind, req, timeout=ns.timeout + float(req.get("planning_time", 0)))
        limits = c.description().get("limits") if kind == "plan" else None
    return body, limits


def guarded(fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """Service and planning errors become one line (plus details) on stderr."""
    def run(ns: argparse.Namespace) -> int:
        from planner.errors import PlanningError

        from .errors import ServiceError, ServiceUnavailable
        try:
            return fn(ns)
        except ServiceUnavailable as e:
            print(f"arduinobot: service unavailable ({e.reason}): {e.message}", file=sys.stderr)
            return EXIT_UNAVAILABLE
        except (ServiceError, PlanningError) as e:
            print(f"arduinobot: {e.code}: {e.message}", file=sys.stderr)
            details = {k: v for k, v in e.details.items() if k not in ("request_id",)}
            if details:
                print(f"  details: {json.dumps(details, default=str)[:2000]}", file=sys.stderr)
            return EXIT_FAIL
    return run


# -- plan ---------------------------------------------------------------------------------
def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plan", help="plan a collision-free, timed motion (through the service or --local)",
        description="Plan a motion to a goal and print a summary: duration, per-joint peak "
        "velocity, acceleration and effort against their limits, and the time each stage "
        "took. Sends a v1 request to `arduinobot serve` (start one first), or plans "
        "in-process with --local exactly as the service would.",
        epilog="examples:\n  arduinobot plan --goal 0.5,0.3,-0.4\n"
        "  arduinobot plan --named reach_left --start 0.2,0,0 --json traj.json\n"
        "  arduinobot plan --position 0,1.0,1.2 --obstacle box:table:1,1,0.1@0,1,0.5\n"
        "  arduinobot plan --request req.json --local --plot traj.png",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    goal = p.add_mutually_exclusive_group()
    goal.add_argument("--goal", metavar="Q", help="joint goal: values of the group's joints "
                      "in the model's order (`arduinobot model` lists them), "
                      "or name=value,...")
    goal.add_argument("--named", metavar="NAME", help="a named SRDF state (home, ...)")
    goal.add_argument("--position", metavar="X,Y,Z", help="a tcp position [m]")
    goal.add_argument("--request", metavar="REQ.json", help="a whole v1 request from a file "
                      "(options given here override its fields)")
    p.add_argument("--start", metavar="Q", help="start: every actuated joint's value in the "
                   "model's order or name=value,...; "
                   "default all 0")
    p.add_argument("--obstacle", action="append", default=[], metavar="SPEC",
                   help="box:ID:sx,sy,sz@x,y,z[@r,p,y], sphere:ID:r@x,y,z or "
                   "cylinder:ID:r,l@x,y,z; repeatable")
    p.add_argument("--group", metavar="NAME", help="a planning group of the model's SRDF, "
                   "or all (default: a named goal's own group, else arm, else the first)")
    p.add_argument("--planner", metavar="NAME", help="an OMPL planner (default RRTConnect)")
    p.add_argument("--planning-time", type=float, metavar="S")
    p.add_argument("--velocity-scaling", type=float, metavar="F")
    p.add_argument("--acceleration-scaling", type=float, metavar="F")
    p.add_argument("--profile", choices=("jerk_limited", "time_optimal"))
    p.add_argument("--sample-rate", type=float, metavar="HZ")
    p.add_argument("--seed", type=int)
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
    p.set_defaults(func=guarded(cmd_plan))


def build_request(ns: argparse.Namespace) -> dict[str, Any]:
    req: dict[str, Any] = {}
    if ns.request:
        req = json.loads(Path(ns.request).read_text("utf-8"))
        if not isinstance(req, dict):
            raise SystemExit(f"arduinobot: error: {ns.request} must hold a JSON object")
    group = ns.group or req.get("group")
    if ns.goal:
        order = () if "=" in ns.goal else joint_order(ns, group)
        req["goal"] = {"joints": joint_map(ns.goal, order, "--goal")}
    elif ns.named:
        req["goal"] = {"named": ns.named}
    elif ns.position:
        req["goal"] = {"position": floats(ns.position, "--position", 3)}
    elif "goal" not in req:
        raise SystemExit("arduinobot: error: give a goal: --goal, --named, --position or "
                         "--request")
    if ns.start:
        order = () if "=" in ns.start else joint_order(ns, "all")
        req["start"] = joint_map(ns.start, order, "--start")
    if ns.obstacle:
        req["obstacles"] = [*req.get("obstacles", []), *map(obstacle, ns.obstacle)]
    for key in ("group", "planner", "planning_time", "velocity_scaling",
                "acceleration_scaling", "profile", "sample_rate", "seed"):
        v = getattr(ns, key)
        if v is not None:
            req[key] = v
    return req


def cmd_plan(ns: argparse.Namespace) -> int:
    from .client import PlanResult
    req = build_request(ns)
    body, limits = run_request(ns, "plan", req)
    res = PlanResult.from_json(body)
    if ns.json:
        text = json.dumps(body, indent=1)
        sys.stdout.write(text + "\n") if ns.json == "-" else Path(ns.json).write_text(text)
    if ns.csv:
        Path(ns.csv).write_text(res.to_csv())
    if ns.plot and not ns.simulate:
        plot_trajectory(res, limits, ns.plot)
    if ns.json != "-":
        print(summary(res, limits))
    if ns.simulate:
        from .simulate import simulate_command
        return simulate_command(ns, body, req)
    return EXIT_OK


def summary(res: Any, limits: Mapping[str, Mapping[str, float | None]] | None) -> str:
    """Duration, per-joint peaks against limits, stage timings."""
    import numpy as np
    lines = [(f"trajectory: {len(res.points)} points, duration {res.duration:.3f} s, "
              f"{len(res.path)} waypoints, planner {res.planner}, request {res.request_id}")]
    lines.append(f"{'joint':<10}{'|v| peak':>10}{'limit':>8}{'|a| peak':>10}{'limit':>8}"
                 f"{'|effort|':>10}{'limit':>8}")
    peaks = {k: np.abs(getattr(res, k)).max(axis=0) if len(res.points) else
             np.zeros(len(res.joint_names)) for k in ("velocities", "accelerations", "efforts")}

    def lim(j: str, kind: str) -> str:
        v = (limits or {}).get(j, {}).get(kind)
        return f"{v:8.2f}" if v is not None else f"{'-':>8}"
    for i, j in enumerate(res.joint_names):
        lines.append(f"{j:<10}{peaks['velocities'][i]:10.3f}{lim(j, 'velocity')}"
                     f"{peaks['accelerations'][i]:10.3f}{lim(j, 'acceleration')}"
                     f"{peaks['efforts'][i]:10.3f}{lim(j, 'effort')}")
    v = res.verification
    if "worst_overall" in v:
        w = v["worst_overall"]
        gap = v.get("min_clearance")
        gap_text = f"{1000 * gap:.1f} mm" if isinstance(gap, (int, float)) else "not measured"
        lines.append(f"verification: {'ok' if v.get('ok') else 'FAILED'}; closest to its "
                     f"limit: {w['quantity']} at {100 * w['ratio']:.1f}% (of the scaled "
                     f"limits); min clearance {gap_text}")
    lines.append("timing: " + ", ".join(f"{k} {1000 * t:.1f} ms" for k, t in res.timing.items()))
    return "\n".join(lines)


def plot_trajectory(res: Any, limits: Mapping[str, Mapping[str, float | None]] | None,
                    out: str) -> None:
    """Positions, velocities, accelerations and efforts over time with their limits
    (dashed), one panel each, saved to ``out``. Needs matplotlib (optional)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise SystemExit("arduinobot: error: --plot needs matplotlib "
                         "(pip install matplotlib)") from None
    t = res.times
    panels = (("positions", "position [rad]", ("lower", "upper")),
              ("velocities", "velocity [rad/s]", ("velocity",)),
              ("accelerations", "acceleration [rad/s²]", ("acceleration",)),
              ("efforts", "effort [N m]", ("effort",)))
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(9, 10))
    for ax, (attr, label, kinds) in zip(axes, panels):
        data = getattr(res, attr)
        for i, j in enumerate(res.joint_names):
            line, = ax.plot(t, data[:, i], label=j)
            for kind in kinds:
                v = (limits or {}).get(j, {}).get(kind)
                if v is None:
                    continue
                for sign in ((1,) if kind in ("lower", "upper") else (1, -1)):
                    ax.axhline(sign * v, color=line.get_color(), ls="--", lw=0.8, alpha=0.6)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"{res.duration:.3f} s, {len(res.points)} samples (dashed: limits)")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
