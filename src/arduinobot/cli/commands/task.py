"""`arduinobot task`: plan a task (a named one of tasks.yaml, by name or number, or a
task file) as a whole, then run it on the MuJoCo twin, the real arm or the service's
robot."""

from __future__ import annotations

import argparse
import json
import logging
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from arduinobot.cli.argtypes import UsageError, file_problem
from arduinobot.cli.commands.execute import add_driver_arg, add_driver_options, driver_options
from arduinobot.cli.common import (
    EXIT_CANCELLED,
    EXIT_FAIL,
    EXIT_OK,
    add_connection_args,
    add_model_args,
    client,
    load_from_args,
)
from arduinobot.contract.outcomes import DEFAULT_ON_CHANGE, ON_CHANGE, succeeded

if TYPE_CHECKING:
    from arduinobot.description import Description
    from arduinobot.planner.tasks import Task

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "task", help="plan a task (steps: move, line, gripper, attach, detach, wait) and "
        "run it",
        description="Plan every step of a task before anything moves, each from where "
        "the last one ends, then run it: on the MuJoCo twin (--sim), the real arm "
        "(--serial) or the service's robot (--remote, planned by the service); without "
        "one of them, plan only. TASK is a name or number of the model's tasks.yaml (its "
        "MoveIt config's, or --tasks FILE; the shipped arduinobot has the course's 0 wake, "
        "1 pick, 2 sleep) or a task file (.json/.yaml, see docs/tasks.md). A task "
        "without a start starts from the robot's state. Ctrl-C stops the arm smoothly.",
        epilog="examples:\n  arduinobot task 1 --sim --fast\n"
        "  arduinobot task pick --serial /dev/ttyACM0\n"
        "  arduinobot task my_task.yaml --sim --report out.json\n"
        "  arduinobot task 2 --remote    # planned and run by `serve`",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("task", nargs="?", metavar="NAME|NUMBER|FILE", help="a named task, its "
                   "number, or a task file (.json, .yaml); without it, list the named tasks")
    add_model_args(p)
    p.add_argument("--tasks", metavar="FILE", help="the named tasks (default: the MoveIt "
                   "config's tasks.yaml)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--sim", action="store_true", help="run on the MuJoCo twin")
    where.add_argument("--serial", nargs="?", const="", metavar="PORT",
                       help="run on the real arm on PORT (default: the URDF's port)")
    where.add_argument("--remote", action="store_true",
                       help="plan and run on the service (`serve`'s robot)")
    add_driver_arg(where)
    p.add_argument("--fast", dest="realtime", action="store_false",
                   help="--sim: as fast as it simulates, not in real time")
    p.add_argument("--rate", type=float, default=100.0, metavar="HZ",
                   help="control rate (default 100)")
    p.add_argument("--baud", type=int, default=None, help="serial baud rate")
    p.add_argument("--boot-wait", type=float, default=2.0, metavar="S",
                   help="seconds to wait after opening the port (default 2)")
    add_driver_options(p)
    p.add_argument("--start-tolerance", type=float, default=0.01, metavar="RAD",
                   help="largest distance of each joint from the task's start (default 0.01)")
    p.add_argument("--move-to-start", action="store_true",
                   help="move to the task's start first (not collision-checked)")
    p.add_argument("--report", metavar="OUT.json", help="write the plan's summary and the "
                   "execution report")
    g = p.add_argument_group("service (--remote)")
    g.add_argument("--on-change", choices=ON_CHANGE, default=DEFAULT_ON_CHANGE,
                   help="when the kept scene changes while the task moves and a remaining "
                   "step (checked with what the task carries there) is no longer "
                   "certified: replan (stop, plan the remaining steps from there and go "
                   "on; default), stop (stop; the report names the step) or ignore")
    add_connection_args(g, timeout_help="seconds to wait for the plan (default 60)",
                        local_help=argparse.SUPPRESS)
    p.set_defaults(func=cmd_task)


def _task_file(text: str) -> Path | None:
    p = Path(text)
    return p if p.suffix.lower() in (".json", ".yaml", ".yml") else None


def _read_body(path: Path) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
        return json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except (OSError, ValueError, yaml.YAMLError) as e:
        raise file_problem(path, e, "task file") from None


def resolve_task(ns: argparse.Namespace, desc: Description) -> Task:
    """The task TASK names: a file, or a named task of --tasks / the MoveIt config's."""
    from arduinobot.description.moveit_config import find_task, read_tasks
    from arduinobot.planner.tasks import task_from_mapping
    f = _task_file(ns.task)
    if f is not None:
        body = _read_body(f)
        if isinstance(body, dict) and "see" in body:  # see and pick (cli/see_task.py)
            if not ns.sim:
                raise UsageError(f"{f}: a task with 'see' runs on the twin: add --sim")
            from arduinobot.cli.see_task import see_on_twin, with_seen
            ns.seen = see_on_twin(body.pop("see"), desc, model=ns.file, args=dict(ns.arg),
                                  obstacles=body.get("obstacles"))
            body = with_seen(body, ns.seen)
        return task_from_mapping(body, name=f.stem)
    tasks_file = Path(ns.tasks) if ns.tasks else desc.config.tasks
    if tasks_file is None:
        raise UsageError(f"no tasks.yaml for '{desc.robot.name}' (give --tasks FILE or a "
                         "task file)")
    named = read_tasks(tasks_file)
    found = find_task(named, ns.task)
    if found is None:
        known = ", ".join(f"{t.number}: {t.name}" if t.number is not None else t.name
                          for t in named.values())
        raise UsageError(f"no task '{ns.task}' in {tasks_file} (tasks: {known or 'none'})")
    return task_from_mapping(found.body, where=f"tasks.{found.name}", name=found.name)


def _print_plan(body: dict[str, Any]) -> None:
    name = body.get("name") or "task"
    print(f"{name}: {len(body['steps'])} steps, {body['duration']:.3f} s, planned in "
          f"{1000 * body['planning_time']:.0f} ms")
    w = max([16, *(len(s.get("label") or "") + 2 for s in body["steps"])])
    for s in body["steps"]:
        ok = "" if "certified" not in s else (
            "  certified, verified" if s["certified"] and s["verified"] else "  NOT VERIFIED")
        carried = f"  carrying {', '.join(s['carried'])}" if s["carried"] else ""
        label = f" {s['label']}" if s.get("label") else ""
        print(f"  {s['index']:2d} {s['kind']:<8s}{label:<{w}s} at {s['start_time']:7.3f} s, "
              f"{s['duration']:6.3f} s{ok}{carried}")
    for c in body.get("choices", ()):
        print(f"  step {c['step']} {c['kind']} {c['object']}: chose {c['candidate']} "
              f"(tried {c['tried']} of {c['candidates']})")


def _list(ns: argparse.Namespace) -> int:
    from arduinobot.description.moveit_config import read_tasks
    desc = load_from_args(ns)
    tasks_file = Path(ns.tasks) if ns.tasks else desc.config.tasks
    if tasks_file is None:
        print(f"no tasks.yaml for '{desc.robot.name}' (give --tasks FILE)")
        return EXIT_OK
    from arduinobot.description.moveit_config import COURSE_TASKS
    whose = (" (the course's task_server tasks, shipped; --tasks FILE for your own)"
             if tasks_file == COURSE_TASKS and desc.config.moveit_package is not None else "")
    print(f"tasks of {tasks_file}{whose}:")
    tasks = read_tasks(tasks_file).values()
    w = max([16, *(len(t.name) + 1 for t in tasks)])
    for t in tasks:
        num = f"{t.number:3d}" if t.number is not None else "  -"
        print(f"  {num} {t.name:<{w}s} {t.description}")
    return EXIT_OK


_MODEL_SUFFIXES = (".urdf", ".xacro")


def cmd_task(ns: argparse.Namespace) -> int:
    if ns.task is not None and ns.file is None and ns.task.lower().endswith(_MODEL_SUFFIXES):
        ns.file, ns.task = ns.task, None  # `task X.xacro`: the model's tasks, listed
    if ns.task is None:
        if ns.sim or ns.serial is not None or ns.remote or ns.driver:
            raise UsageError("give the task to run: NAME, NUMBER or FILE (without one, "
                             "`arduinobot task` lists the named tasks)")
        return _list(ns)
    driver_options(ns)  # --port/--driver-option without --driver: a usage error now
    if ns.remote:
        return _remote(ns)
    if not ns.realtime and not ns.sim:
        raise UsageError("--fast is for --sim: hardware runs in real time")
    from arduinobot.planner.planning.pipeline import MotionPlanner
    from arduinobot.planner.tasks import plan_task
    from arduinobot.service.task.task_service import planned_body

    desc = load_from_args(ns)
    task = resolve_task(ns, desc)
    robot = None
    if ns.sim or ns.serial is not None or ns.driver:
        from arduinobot.cli.commands.execute import robot_spec
        ns.no_robot = False
        robot = robot_spec(ns).open(desc, obstacles=[])
    try:
        if robot is not None and task.start is None:
            from dataclasses import replace

            from arduinobot.execution.executor import plan_start
            task = replace(task, start=plan_start(robot, desc))
        result = plan_task(MotionPlanner(desc), task)
        # with --report, each step's plan too: `arduinobot view --task OUT.json` plays it
        body = planned_body(result, name=task.name, trajectories=bool(ns.report))
        _print_plan(body)
        out: dict[str, Any] = {"planned": body}
        code = EXIT_OK
        if robot is not None:
            out["execution"] = _run(ns, robot, desc, task, result)
            code = _exit_code(out["execution"].get("outcome"))
    finally:
        if robot is not None:
            robot.close()
    _write_report(ns, out)
    return code


def _run(ns: argparse.Namespace, robot: Any, desc: Description, task: Task, result: Any
         ) -> dict[str, Any]:
    from arduinobot.cli.common import sigint_sets
    from arduinobot.execution.executor import ExecuteOptions, Executor
    from arduinobot.execution.segments import SampledTrajectory
    ts, q, qd, qdd = result.samples(ns.rate)
    traj = SampledTrajectory(tuple(result.joint_names), ts, q, qd, qdd)
    opts = ExecuteOptions(rate=ns.rate, start_tolerance=ns.start_tolerance,
                          move_to_start=ns.move_to_start, realtime=ns.realtime)
    on_tick = None
    objects: tuple[Any, ...] = ()
    if ns.sim:  # the task's scene in the twin, what it picks up a free body it grips
        from arduinobot.execution.robots.twin_tasks import grasp_schedule, task_objects, without
        objects = task_objects(task, result)
        seen = getattr(ns, "seen", None)
        if seen is not None:  # planned as seen; in the twin, where it really is
            from dataclasses import replace
            objects = tuple(replace(a, shape=seen.truth[a.id]) if a.id in seen.truth else a
                            for a in objects)
        robot.set_scene(without(result.start_obstacles, objects), loose=objects,
                        ground=task.ground)
        on_tick = grasp_schedule(robot, result)
    ex = Executor.for_description(robot, desc, options=opts, on_tick=on_tick)
    ex.check_start(traj)
    where = "the MuJoCo twin" if ns.sim else getattr(robot, "port", "the arm")
    cancel = threading.Event()
    # Ctrl-C is ours before the line that says so: one pressed right after it was lost
    # (exit 0, the whole motion run) on a loaded machine
    with sigint_sets(cancel):
        print(f"executing {traj.duration:.3f} s on {where} (Ctrl-C stops smoothly)",
              file=sys.stderr)
        report = ex.execute(traj, cancel=cancel).to_dict()
    print(f"{report['outcome']}: {report['duration']:.3f} s")
    if getattr(ns, "seen", None) is not None:
        report["seen"] = list(ns.seen.detections)
    if objects:  # where the simulated objects ended (MuJoCo's state, not the plan's)
        report["objects"] = {a.id: robot.object_pose(a.id)[:3, 3].tolist() for a in objects}
        _print_objects(report["objects"])
    return report


def _print_objects(objects: dict[str, list[float]]) -> None:
    for k, xyz in objects.items():
        print(f"  {k} ends at {xyz[0]:.3f} {xyz[1]:.3f} {xyz[2]:.3f} m (simulated)")


def _write_report(ns: argparse.Namespace, out: dict[str, Any]) -> None:
    if ns.report:
        Path(ns.report).write_text(json.dumps(out, indent=1))
        print(f"wrote {ns.report}")


def _remote(ns: argparse.Namespace) -> int:
    """Plan and run on the service: ``<prefix>/task`` with ``execute``
    (:meth:`PlannerClient.task`); Ctrl-C cancels the execution smoothly."""
    from arduinobot.cli.common import sigint_sets
    from arduinobot.client.stream import ExecutionEvent
    if ns.file or any((ns.package_dir, ns.arg, ns.moveit_config, ns.srdf, ns.joint_limits)):
        raise UsageError("--remote runs the service's robot: its model is the service's")
    f = _task_file(ns.task)
    task: str | int | dict[str, Any] = _read_body(f) if f is not None else \
        int(ns.task) if ns.task.isdigit() else ns.task

    def on_event(ev: ExecutionEvent) -> None:
        if ev.event == "started":
            print(f"executing {ev.execution}: {ev.duration or 0.0:.3f} s on the "
                  "service's robot (Ctrl-C stops smoothly)", file=sys.stderr)
    cancel = threading.Event()
    with client(ns) as c, sigint_sets(cancel):
        reply = c.task(task, execute=True, start_tolerance=ns.start_tolerance,
                       move_to_start=ns.move_to_start, trajectories=bool(ns.report),
                       on_change=ns.on_change, on_planned=lambda body: _print_plan(dict(body)), on_event=on_event,
                       cancel=cancel)
    out: dict[str, Any] = {"planned": reply.planned}
    if reply.report is not None:
        out["execution"] = dict(reply.report)
        print(f"{reply.report['outcome']}: {reply.report['duration']:.3f} s")
        if reply.report.get("objects"):  # the service's twin simulated them
            _print_objects(reply.report["objects"])
    _write_report(ns, out)
    return _exit_code(out.get("execution", {}).get("outcome"))


def _exit_code(outcome: str | None) -> int:
    """The exit code of an execution's outcome: 0 completed or written (an arm that
    reports nothing back), 130 cancelled (Ctrl-C, as ``execute``), 1 otherwise (nothing
    executed, or it failed)."""
    if succeeded(outcome):
        return EXIT_OK
    return EXIT_CANCELLED if outcome == "cancelled" else EXIT_FAIL
