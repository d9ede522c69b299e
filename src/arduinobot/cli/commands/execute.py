"""`arduinobot execute`: run a trajectory on the real arm (serial), the MuJoCo twin, the
service's robot (--remote), streaming it at the controller rate, or a ROS 2 workspace's
joint_trajectory_controllers over rmw_zenoh (--ros2)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
import threading
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

from arduinobot.cli.argtypes import UsageError, json_object
from arduinobot.cli.common import (
    EXIT_CANCELLED,
    EXIT_FAIL,
    EXIT_OK,
    add_connection_args,
    add_model_args,
    client,
    connect,
    load_from_args,
    sigint_sets,
)
from arduinobot.cli.ros2_options import add_ros2_args, ros2_settings
from arduinobot.contract.outcomes import DEFAULT_ON_CHANGE, ON_CHANGE, succeeded

if TYPE_CHECKING:  # the executor and the drivers load with the command, not with the CLI
    from arduinobot.client.stream import ExecutionEvent
    from arduinobot.description import Description
    from arduinobot.execution.robots.mjcf import Progress
    from arduinobot.execution.robots.spec import RobotSpec

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "execute", help="run a trajectory on the arm (serial), its MuJoCo twin, or the "
        "service's robot",
        description="Stream a trajectory to a robot at the controller rate (100 Hz by "
        "default), publishing <prefix>/joint_states while it moves. TRAJ.json is what "
        "`plan --json` writes; --named/--request plan first (through the service, or "
        "--local), starting from the robot's current state. The robot is FILE's model; "
        "without FILE, the service's own robot when the service plans, else the shipped "
        "arduinobot; a trajectory that does not fit it (joints, limits) is refused. The "
        "robot must be where the trajectory begins (--start-tolerance), or --move-to-start "
        "moves it there first (jerk-limited, a straight line in joint space, not "
        "collision-checked). Ctrl-C stops the arm smoothly (jerk-limited, within its "
        "limits) and exits 130.",
        epilog="examples:\n  arduinobot plan --named reach_left --json traj.json\n"
        "  arduinobot execute traj.json --serial /dev/ttyACM0\n"
        "  arduinobot execute traj.json --sim --fast --no-publish\n"
        "  arduinobot execute traj.json so101.urdf --driver feetech --port /dev/ttyACM0 "
        "--driver-option calibration=so101.json\n"
        "  arduinobot execute --named home --sim --local\n"
        "  arduinobot execute ~/ws/src/arduinobot_description/urdf/arduinobot.urdf.xacro "
        "--named home --group arm_robot --sim --local\n"
        "  arduinobot execute --named reach_left --remote    # on `serve`'s robot\n"
        "  arduinobot execute traj.json --ros2    # arm_controller, gripper_controller "
        "(rmw_zenohd on tcp/127.0.0.1:7447)")
    p.add_argument("paths", nargs="*", metavar="TRAJ.json|FILE",
                   help="a plan reply (plan --json) or {joint_names, points} trajectory "
                   "(.json), and/or the robot's model (a .urdf or .xacro file)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--named", metavar="NAME", help="plan to a named SRDF state first")
    src.add_argument("--request", metavar="REQ.json", type=json_object,
                     help="plan this v1 request first (without a start, from the robot's "
                     "state)")
    p.add_argument("--group", metavar="NAME", help="the planning group of --named (a "
                   "state several groups define, as MoveIt's `home`)")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--serial", nargs="?", const="", metavar="PORT",
                       help="the real arm on PORT (default: the URDF's ros2_control "
                       "<hardware> 'port' param)")
    where.add_argument("--sim", action="store_true", help="the MuJoCo twin (needs mujoco)")
    add_driver_arg(where)
    where.add_argument("--remote", action="store_true",
                       help="the service's robot (<prefix>/execute; `serve --serial` or its "
                       "twin); a lost client stops the arm")
    where.add_argument("--ros2", action="store_true",
                       help="a ROS 2 workspace's joint_trajectory_controllers (ros2_control) "
                       "over rmw_zenoh, through the router --connect names (default "
                       "tcp/127.0.0.1:7447, rmw_zenohd's); needs the ros2 extra")
    r = p.add_argument_group("robot")
    _add_robot_args(r)
    _add_run_args(r)
    ros = p.add_argument_group("ROS 2 (--ros2; see docs/ros2.md)")
    _add_controller_args(ros)
    add_ros2_args(ros)
    g = p.add_argument_group("service (planning, joint_states, --remote)")
    add_connection_args(g, timeout_help="seconds to wait for a plan (default 60)",
                        local_help="plan in this process, not through the service")
    p.add_argument("--description", metavar="PATH", dest="description_path",
                   help="the robot's URDF/xacro, as FILE (default: see above)")
    add_model_args(p, file_arg=False)
    p.set_defaults(func=cmd_execute)


def _add_run_args(r: argparse._ArgumentGroup) -> None:
    """How the run goes: pacing (twin), the start check, blending, what it reports."""
    pace = r.add_mutually_exclusive_group()
    pace.add_argument("--realtime", dest="realtime", action="store_true", default=True,
                      help="pace the twin in real time (default)")
    pace.add_argument("--fast", dest="realtime", action="store_false",
                      help="run the twin as fast as it computes (--sim only)")
    r.add_argument("--start-tolerance", type=float, default=0.01, metavar="RAD",
                   help="largest allowed distance of each joint from the trajectory's "
                   "start (default 0.01 rad)")
    r.add_argument("--move-to-start", action="store_true",
                   help="move to the trajectory's start first instead of refusing")
    r.add_argument("--blend", action="store_true",
                   help="with --remote and a goal: blend into the motion in progress "
                   "(planned from its state --blend-lead ahead) instead of waiting for it")
    r.add_argument("--blend-lead", type=float, default=None, metavar="S",
                   help="with --blend: how far ahead of the moving arm the blend is "
                   "planned from, in [0.05, 30] s (default 0.8 s); it must cover the "
                   "planning, or the blend is TOO_LATE")
    r.add_argument("--on-change", choices=ON_CHANGE, default=DEFAULT_ON_CHANGE,
                   help="with --remote: when the kept scene changes while the arm moves and "
                   "the rest of the motion is no longer certified, replan (stop before it "
                   "and plan on to the same goal; default), stop (stop before it) or "
                   "ignore")
    r.add_argument("--no-publish", action="store_true",
                   help="do not publish <prefix>/joint_states")
    r.add_argument("--report", metavar="OUT.json", help="write the execution report")


def _add_controller_args(ros: argparse._ArgumentGroup) -> None:
    """--ros2's controllers and how the trajectory reaches them."""
    ros.add_argument("--controller", action="append", metavar="NAME",
                     help="send to this controller, repeatable (default: every controller "
                     "of the MoveIt config's moveit_controllers.yaml that moves a joint of "
                     "the trajectory; without that file, <group>_controller per SRDF group)")
    ros.add_argument("--ros2-topic", action="store_true",
                     help="publish trajectory_msgs/msg/JointTrajectory on "
                     "/<controller>/joint_trajectory instead of the FollowJointTrajectory "
                     "action (no result: waits the trajectory's duration)")
    ros.add_argument("--control-msgs", choices=("auto", "jazzy", "rolling"), default="auto",
                     help="control_msgs' FollowJointTrajectory feedback: jazzy (5.x) or "
                     "rolling (6.3+, with index); default auto: the one the controller "
                     "announces. Only the feedback differs")


def add_serve_args(p: argparse.ArgumentParser) -> None:
    """``serve``'s robot options: what ``<prefix>/execute`` drives."""
    g = p.add_argument_group("robot (<prefix>/execute)")
    w = g.add_mutually_exclusive_group()
    w.add_argument("--serial", nargs="?", const="", metavar="PORT",
                   help="drive the real arm on PORT (default: the URDF's ros2_control "
                   "port); default: the MuJoCo twin")
    add_driver_arg(w)
    w.add_argument("--no-robot", action="store_true", help="serve no <prefix>/execute robot")
    _add_robot_args(g)


def add_driver_arg(where: argparse._MutuallyExclusiveGroup) -> None:
    """``--driver``: a plug-in driver instead of --serial/--sim (docs/drivers.md)."""
    where.add_argument("--driver", metavar="NAME|module:Class",
                       help="a plug-in driver: an 'arduinobot.drivers' entry point "
                       "(feetech: Feetech STS/SCS bus servos) or module:Class; with "
                       "--port and --driver-option (docs/drivers.md)")


def add_driver_options(g: argparse._ActionsContainer) -> None:
    """--driver's port and options."""
    g.add_argument("--port", metavar="PORT", help="--driver's port (e.g. /dev/ttyACM0)")
    g.add_argument("--driver-option", action="append", default=[], metavar="KEY=VALUE",
                   help="an option of --driver, repeatable (feetech: calibration=FILE, "
                   "gripper=JOINT, max_error=RAD, timeout=S, on_close=hold|release, "
                   "series=sts|scs, motor.JOINT=NAME)")


def driver_options(ns: argparse.Namespace) -> tuple[tuple[str, str], ...]:
    """``--driver-option`` pairs; --port/--driver-option need --driver.

    Raises:
        UsageError: an option without ``=``, or options without --driver.
    """
    opts = list(getattr(ns, "driver_option", None) or [])
    if not getattr(ns, "driver", None):
        if opts or getattr(ns, "port", None):
            raise UsageError("--port and --driver-option go with --driver")
        return ()
    out = []
    for o in opts:
        key, eq, value = o.partition("=")
        if not eq or not key:
            raise UsageError(f"--driver-option {o!r}: write KEY=VALUE")
        out.append((key.strip(), value))
    return tuple(out)


# arduinobot.ros2.attachment.LAYOUTS, spelled out: the ros2 extra is not imported to build the parser
def _add_robot_args(g: argparse._ArgumentGroup) -> None:
    add_driver_options(g)
    g.add_argument("--baud", type=int, default=None, help="serial baud rate (default "
                   "115200, or the URDF's baud_rate param)")
    g.add_argument("--rate", type=float, default=100.0, metavar="HZ",
                   help="control rate (default 100)")
    g.add_argument("--boot-wait", type=float, default=2.0, metavar="S",
                   help="seconds to wait after opening the port: an Arduino resets when "
                   "the port opens (default 2)")


def robot_spec(ns: argparse.Namespace, *, progress: Progress | None = None) -> RobotSpec:
    """The :class:`arduinobot.execution.RobotSpec` of the robot options (``serve``'s, or
    ``execute``'s --serial/--sim/--driver); a twin keeps its mesh pieces in the user's cache
    (``serve --no-cache``: nowhere) and tells ``progress`` what a first build computes."""
    from arduinobot.execution.robots.spec import RobotSpec
    from arduinobot.service.process.disk_cache import DiskCache
    if getattr(ns, "no_robot", False):
        return RobotSpec(kind="none")
    options = driver_options(ns)
    if getattr(ns, "driver", None):
        return RobotSpec(kind="driver", driver=ns.driver, port=ns.port, baud=ns.baud,
                         rate=ns.rate, driver_options=options)
    if getattr(ns, "serial", None) is not None:
        return RobotSpec(kind="serial", port=ns.serial or None, baud=ns.baud, rate=ns.rate,
                         boot_wait=ns.boot_wait)
    cache = None if getattr(ns, "no_cache", False) else DiskCache(getattr(ns, "cache_dir", None))
    return RobotSpec(kind="sim", rate=ns.rate, cache=cache, progress=progress)


def _split_paths(ns: argparse.Namespace) -> None:
    """TRAJ.json and FILE from the positional paths (a .json is the trajectory)."""
    trajs = [p for p in ns.paths if p.lower().endswith(".json")]
    models = [p for p in ns.paths if not p.lower().endswith(".json")]
    if len(trajs) > 1 or len(models) > 1:
        raise UsageError("give at most one TRAJ.json and one model FILE (.urdf/.xacro)")
    ns.trajectory = trajs[0] if trajs else None
    ns.file = models[0] if models else None
    if ns.file and ns.description_path:
        raise UsageError("give the model as FILE or --description, not both")


def _plan_request(ns: argparse.Namespace) -> dict[str, Any] | None:
    """The plan request of --named/--request (None: TRAJ.json is the trajectory).

    Raises:
        UsageError: flags that do not go together.
    """
    _split_paths(ns)
    driver_options(ns)  # --port/--driver-option without --driver: a usage error now
    if ns.trajectory and (ns.named or ns.request):
        raise UsageError("give TRAJ.json or --named/--request, not both")
    if not (ns.trajectory or ns.named or ns.request):
        raise UsageError("give TRAJ.json, --named or --request")
    if not ns.realtime and not ns.sim:
        raise UsageError("--fast is for --sim: hardware runs in real time")
    if ns.blend and not (ns.remote and (ns.named or ns.request)):
        raise UsageError("--blend needs --remote and a goal (--named/--request)")
    if ns.blend_lead is not None and not ns.blend:
        raise UsageError("--blend-lead needs --blend")
    if ns.group and not ns.named:
        raise UsageError("--group goes with --named (a request names its own group)")
    if not ns.ros2:
        off = [f for f, v in (("--controller", ns.controller), ("--ros2-topic", ns.ros2_topic),
                              ("--control-msgs", ns.control_msgs != "auto")) if v]
        if off:
            raise UsageError(f"{', '.join(off)} {'go' if len(off) > 1 else 'goes'} with "
                             "--ros2")
    elif ns.move_to_start:
        raise UsageError("--move-to-start is not for --ros2: the controller plays the "
                         "trajectory from where it is; plan from the robot's state")
    if ns.remote and (ns.file or ns.description_path):
        raise UsageError("--remote executes on the service's robot: its model is the "
                         "service's, not FILE")
    if ns.named:
        return {"goal": {"named": ns.named}, **({"group": ns.group} if ns.group else {})}
    return ns.request


def _model(ns: argparse.Namespace, planned_by_service: bool) -> Description:
    """The robot's model: FILE (or --description); without one, the service's own robot
    when the service plans the motion, else the shipped arduinobot."""
    if ns.file or ns.description_path or ns.local or not planned_by_service:
        return load_from_args(ns)
    from arduinobot.cli.remote_model import model_of_service
    with client(ns) as c:
        return model_of_service(c.description())


def cmd_execute(ns: argparse.Namespace) -> int:
    req = _plan_request(ns)
    if ns.remote:
        return _remote(ns, req)
    settings = ros2_settings(ns)
    if settings is not None:
        from arduinobot.cli.ros2_execute import execute_on_controllers
        return execute_on_controllers(ns, req, settings, _model(ns, req is not None))
    from arduinobot.cli.remote_model import progress_printer
    from arduinobot.client.replies import PlanReply
    from arduinobot.execution.executor import ExecuteOptions, Executor, plan_start
    from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
    from arduinobot.execution.segments import SampledTrajectory, check_fits
    desc = _model(ns, req is not None)
    with ExitStack() as held:  # the robot and the joint_states session, closed at the end
        robot = held.enter_context(robot_spec(ns, progress=progress_printer()).open(
            desc, obstacles=(req or {}).get("obstacles", [])))
        if req is not None:
            if "start" not in req:  # plan from where the robot is
                req["start"] = plan_start(robot, desc)
            with connect(ns, model_drives_robot=True) as service:
                traj = SampledTrajectory.of(PlanReply.parse(service.request("plan", req)))
        else:
            traj = SampledTrajectory.load(ns.trajectory)
        check_fits(traj, desc)
        publish = None if ns.no_publish else _publisher(ns, held)
        cancel = threading.Event()
        opts = ExecuteOptions(rate=ns.rate, start_tolerance=ns.start_tolerance,
                              move_to_start=ns.move_to_start, realtime=ns.realtime)
        ex = Executor.for_description(robot, desc, options=opts, on_tick=publish)
        ex.check_start(traj)
        where = "the MuJoCo twin" if ns.sim else getattr(robot, "port", "the arm")
        with sigint_sets(cancel):  # ours before the line that says Ctrl-C stops it
            print(f"executing {traj.duration:.3f} s on {where} of '{desc.robot.name}' at "
                  f"{ns.rate:g} Hz (Ctrl-C stops smoothly)", file=sys.stderr)
            report = ex.execute(traj, cancel=cancel)
        summary = report.to_dict()
        if isinstance(robot, SimArduinobot):
            summary["simulation"] = robot.stats().to_dict()
        return _report(ns, summary)


def _publisher(ns: argparse.Namespace, held: ExitStack) -> Any:
    """A joint_states publisher on a client session ``held`` closes, or None with a
    warning when no zenoh peer is reachable."""
    from arduinobot.client.errors import ServiceUnavailable
    from arduinobot.execution.joint_states import JointStatePublisher
    try:
        c = held.enter_context(client(ns))
    except ServiceUnavailable as e:
        log.warning("not publishing %s/joint_states: %s; --no-publish silences this",
                    ns.prefix, e.message)
        return None
    return JointStatePublisher(c.session, ns.prefix)


def _report(ns: argparse.Namespace, r: dict[str, Any]) -> int:
    """Print the execution report ``r`` (and write it to --report); the exit code of its
    outcome."""
    pk = r["peak_ratio"]
    lines = [f"{r['outcome']}: {r['duration']:.3f} s, {r['ticks']} ticks ({r['late_ticks']} "
             f"late, max lateness {1000 * r['max_lateness']:.1f} ms)"]
    if r["outcome"] == "written":
        lines.append("every setpoint was written to the port; this arm reports nothing "
                     "back, so nobody saw it take them (watch it)")
    if r.get("cancelled_at") is not None:
        how = "stopped for a scene change" if r["outcome"] == "stopped" else "cancelled"
        lines.append(f"{how} at {r['cancelled_at']:.3f} s of "
                     f"{r['trajectory_duration']:.3f} s; stopped in {r['stop_time']:.3f} s"
                     + (f" ({r['stopped_because']})" if r.get("stopped_because") else ""))
    if r.get("legs"):
        lines.append(f"{len(r['legs'])} legs (replanned {len(r['legs']) - 1} times after "
                     "scene changes); this report is the last leg's")
    lines.append("commanded peaks vs limits: " + ", ".join(
        f"{k} {100 * v:.0f}%" for k, v in pk.items()))
    lines.append("tracking error (max per joint): " + ", ".join(
        f"{n} {1000 * e:.2f} mrad" for n, e in zip(r["joint_names"], r["max_tracking_error"])))
    sim = r.get("simulation")
    if sim:
        lines.append("torque needed / servo peak / limit: " + ", ".join(
            f"{n} {ff:.2f}/{f:.2f}/{e:.0f} N m" for n, ff, f, e in zip(
                r["joint_names"], sim["peak_feedforward"], sim["peak_force"], sim["effort"])))
        lines.append(f"saturated steps {sim['saturated_steps']}/{sim['steps']}; contacts: "
                     + (", ".join("/".join(p) for p in sim["contacts"]) or "none"))
    print("\n".join(lines))
    if ns.report:
        Path(ns.report).write_text(json.dumps(r, indent=1))
    if succeeded(r["outcome"]):
        return EXIT_OK
    return EXIT_FAIL if r["outcome"] == "stopped" else EXIT_CANCELLED


def _remote(ns: argparse.Namespace, req: dict[str, Any] | None) -> int:
    """Execute on the service's robot through :meth:`PlannerClient.execute`: its events
    on stderr; Ctrl-C cancels (the arm stops smoothly); a lost client stops the arm."""
    from arduinobot.client.stream import describe
    from arduinobot.execution.segments import read_json
    with client(ns) as c:
        if ns.blend:
            msg = c.blend(req or {}, lead=ns.blend_lead)
            print(f"blended into {msg['execution']} at tick {msg['tick']}: the new motion "
                  f"takes {msg['duration']:.3f} s")
            return EXIT_OK

        def on_event(ev: ExecutionEvent) -> None:
            if ev.event == "started":
                print(f"executing {ev.execution}: {ev.duration:.3f} s on the service's "
                      "robot (Ctrl-C stops smoothly)", file=sys.stderr)
            elif (line := describe(ev)) is not None:  # a reaction to a scene change
                print(line, file=sys.stderr)
        cancel = threading.Event()
        traj = None if req is not None else read_json(ns.trajectory)
        with sigint_sets(cancel):
            done = c.execute(traj, plan=req, start_tolerance=ns.start_tolerance,
                             move_to_start=ns.move_to_start, on_change=ns.on_change,
                             on_event=on_event,
                             cancel=cancel)
    return _report(ns, dict(done.report or {}))  # a finished event has one (its parse)


# -- --ros2: a ROS 2 workspace's joint_trajectory_controllers ------------------------------------

