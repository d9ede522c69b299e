"""`arduinobot view`: the robot in a browser, with joint sliders, collisions, planning and
trajectory playback (needs the `view` extra: viser, matplotlib)."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from planner.scene import Obstacle

from .argtypes import UsageError
from .common import EXIT_FAIL, EXIT_OK, add_model_args, load_from_args, wrote

if TYPE_CHECKING:  # the viewer's modules need the view extra: imported when it runs
    from description import Description
    from viewer.task_view import TaskPlayback
    from viewer.trajectory import PlaybackTrajectory


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view", help="show the robot in a browser: joint sliders, collisions, plan and play",
        description="Serve a web page (on localhost) showing the robot's meshes at the "
        "sliders' joint values, in distinct colours, over a ground grid with +z up; links "
        "in collision turn red and the colliding pairs are listed. A planning panel plans "
        "from the shown pose to a marked pose or a named state (in-process, or through a "
        "running 'arduinobot serve' with --connect) and plays the trajectory with a time "
        "scrubber, speed control and plots of positions, velocities, accelerations and "
        "efforts against their limits. Needs: pip install -e '.[view]'.",
        epilog="examples:\n  arduinobot view                       # then open "
        "http://127.0.0.1:8080\n  arduinobot view --scene table.json --trajectory plan.json\n"
        "  arduinobot view --connect tcp/127.0.0.1:7447\n"
        "  arduinobot view --trajectory plan.json --plot-png plan.png   # no server\n"
        "  arduinobot view my_robot.urdf.xacro --package-dir ~/ws/src/my_robot_description")
    add_model_args(p)
    p.add_argument("--port", type=int, default=8080, metavar="P",
                   help="the page's port (default 8080; the next free one if taken)")
    p.add_argument("--host", default="127.0.0.1",
                   help="the address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--obstacle", action="append", default=[], metavar="JSON",
                   help="an obstacle as the service's JSON, e.g. '{\"id\": \"table\", "
                   "\"shape\": \"box\", \"size\": [1, 1, 0.1], \"xyz\": [0, 0.8, 0.5]}'; "
                   "repeatable")
    p.add_argument("--scene", metavar="FILE.json",
                   help="obstacles from a JSON file: a list of obstacles or "
                   "{\"obstacles\": [...]}")
    p.add_argument("--trajectory", metavar="FILE.json",
                   help="a trajectory to play, as written by 'arduinobot plan --json'")
    p.add_argument("--task", metavar="FILE.json",
                   help="a planned task to play (`arduinobot task ... --report FILE.json`): "
                   "its steps marked on the scrubber, its scene, what it carries")
    p.add_argument("--plot-png", metavar="PATH",
                   help="write the --trajectory's plots to PATH as PNG and exit")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--connect", metavar="ENDPOINT",
                     help="plan through a running 'arduinobot serve' at ENDPOINT "
                     "(e.g. tcp/127.0.0.1:7447)")
    src.add_argument("--local", action="store_true",
                     help="plan in this process (the default without --connect)")
    p.add_argument("--follow", action="store_true",
                   help="show the live <prefix>/joint_states of a running 'arduinobot "
                   "execute' (sim or real arm), through --connect (default "
                   "tcp/127.0.0.1:7447)")
    p.add_argument("--prefix", default="arduinobot", help="the service's key prefix "
                   "(for --follow)")
    p.set_defaults(func=cmd_view)


def read_obstacles(items: list[str], scene: str | None) -> tuple[Obstacle, ...]:
    """Obstacles from --obstacle JSON strings and a --scene file.

    Raises:
        planner.errors.InvalidRequest: naming the bad field.
        UsageError: a file or string that is not JSON.
    """
    raw: list[tuple[object, str]] = []
    if scene:
        try:
            data = json.loads(Path(scene).read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise UsageError(f"--scene {scene}: {e}") from None
        if isinstance(data, dict):
            data = data.get("obstacles", [])
        if not isinstance(data, list):
            raise UsageError(f"--scene {scene}: expected a list of obstacles or "
                             "{\"obstacles\": [...]}")
        raw += [(o, f"scene.obstacles[{i}]") for i, o in enumerate(data)]
    for i, text in enumerate(items):
        try:
            raw.append((json.loads(text), f"--obstacle[{i}]"))
        except json.JSONDecodeError as e:
            raise UsageError(f"--obstacle '{text}' is not JSON: {e}") from None
    return tuple(Obstacle.from_mapping(o, where=w) for o, w in raw)


def cmd_view(ns: argparse.Namespace) -> int:
    from viewer import ViewerUnavailable
    from viewer.trajectory import PlaybackTrajectory

    try:
        obstacles = read_obstacles(ns.obstacle, ns.scene)
        traj = PlaybackTrajectory.from_file(ns.trajectory) if ns.trajectory else None
        d = load_from_args(ns)
        task = None
        if ns.task:
            if traj is not None:
                raise UsageError("give --trajectory or --task, not both")
            task = _read_task(ns.task, d)
            traj, obstacles = task.trajectory, (*obstacles, *task.obstacles)
        if ns.plot_png:
            return _write_png(ns, d, traj)
        return _serve(ns, d, obstacles, traj, task)
    except ViewerUnavailable as e:
        print(f"arduinobot: {e}", file=sys.stderr)
        return EXIT_FAIL


def _read_task(path: str, d: Description) -> TaskPlayback:
    from planner.kinematics.chain import Kinematics
    from viewer.task_view import TaskPlayback
    try:
        body = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise UsageError(f"--task {path}: unreadable ({e})") from None
    return TaskPlayback.from_reply(body, Kinematics(d.robot))


def _write_png(ns: argparse.Namespace, d: Description, traj: PlaybackTrajectory | None) -> int:
    from viewer.plots import joint_limits, plot_panels, plot_png

    if traj is None:
        raise UsageError("--plot-png needs --trajectory FILE.json or --task FILE.json")
    panels = plot_panels(traj, joint_limits(d, traj.joint_names))
    Path(ns.plot_png).write_bytes(plot_png(panels, title=str(ns.trajectory)))
    wrote(ns.plot_png, f"plots of {len(traj.times)} samples")
    return EXIT_OK


def _serve(ns: argparse.Namespace, d: Description, obstacles: tuple[Obstacle, ...],
           traj: PlaybackTrajectory | None, task: TaskPlayback | None = None) -> int:
    from viewer.app import RobotViewer
    from viewer.plan_panel import PlanningPanel
    from viewer.planning import LocalBackend, RemoteBackend
    from viewer.playback import PlaybackPanel

    # the backend first: it refuses what the service cannot plan around before a page opens
    backend = (RemoteBackend(ns.connect, obstacles=obstacles) if ns.connect
               else LocalBackend(d, obstacles=obstacles))
    viewer = RobotViewer(d, obstacles=obstacles, host=ns.host, port=ns.port)
    playback = PlaybackPanel(viewer)
    PlanningPanel(viewer, playback, backend)
    if task is not None:
        from viewer.task_view import show_task
        show_task(viewer, playback, task)
    elif traj is not None:
        playback.load(traj, source=Path(ns.trajectory).name)
    follower = None
    if ns.follow:
        from viewer.follow import JointStateFollower
        follower = JointStateFollower(viewer, ns.connect or "tcp/127.0.0.1:7447",
                                      prefix=ns.prefix)
    # the handlers before the ready line: a Ctrl-C right after it must stop the page's
    # threads too, not raise past them (they would keep the process alive)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    print(f"arduinobot view: {d.robot.name} at {viewer.url} (Ctrl-C stops)",
          flush=True)
    stop.wait()
    if follower is not None:
        follower.close()
    playback.close()
    viewer.close()
    return EXIT_OK
