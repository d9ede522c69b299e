"""`arduinobot view`: the robot in a browser, with joint sliders, collisions, planning and
trajectory playback (needs the `view` extra: viser, matplotlib)."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from arduinobot.cli.argtypes import UsageError, file_problem, key_prefix
from arduinobot.cli.common import EXIT_FAIL, EXIT_OK, add_model_args, load_from_args, wrote
from arduinobot.client.errors import ServiceUnavailable
from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.zconfig import DEFAULT_ENDPOINT
from arduinobot.scene.obstacles import Obstacle

if TYPE_CHECKING:  # the viewer's modules need the view extra: imported when it runs
    from arduinobot.client.client import PlannerClient
    from arduinobot.description import Description
    from arduinobot.viewer.scene_view import ViewerScene
    from arduinobot.viewer.task_view import TaskPlayback
    from arduinobot.viewer.trajectory import PlaybackTrajectory


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view", help="show the robot in a browser: joint sliders, collisions, plan and play",
        description="Serve a web page (on localhost) showing the robot's meshes at the "
        "sliders' joint values, in distinct colours, over a ground grid with +z up; links "
        "in collision turn red and the colliding pairs are listed. A planning panel plans "
        "from the shown pose to a marked pose or a named state (in-process, or through a "
        "running 'arduinobot serve' with --connect) and plays the trajectory with a time "
        "scrubber, speed control and plots of positions, velocities, accelerations and "
        "efforts against their limits. Connected to a service (--connect, --follow) it "
        "draws the service's kept scene (<prefix>/scene): its objects, and the objects the "
        "robot carries on their link. Needs: pip install -e '.[view]'.",
        epilog="examples:\n  arduinobot view                       # then open "
        "http://127.0.0.1:8080\n  arduinobot view --scene table.json --trajectory plan.json\n"
        "  arduinobot view --connect tcp/127.0.0.1:7447   # with the service's scene\n"
        "  arduinobot view --local --scene cell.json   # a scene saved by `scene save`\n"
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
                   help="a scene saved by 'arduinobot scene save' ({\"objects\": ...}): "
                   "drawn, carried objects on their link, and planned around in this "
                   "process; or obstacles sent with each plan: a list of obstacles or "
                   "{\"obstacles\": [...]}")
    p.add_argument("--trajectory", metavar="FILE.json",
                   help="a trajectory to play, as written by 'arduinobot plan --json'")
    p.add_argument("--task", metavar="FILE.json",
                   help="a planned task to play (`arduinobot task ... --report FILE.json`): "
                   "its steps marked on the scrubber, its scene, what it carries")
    p.add_argument("--plot-png", metavar="PATH",
                   help="write the --trajectory's plots to PATH as PNG and exit")
    p.add_argument("--png", metavar="PATH",
                   help="write a picture of the robot and its scene (obstacles, the kept "
                   "scene's objects, what the robot carries) to PATH as PNG and exit, "
                   "without a browser")
    p.add_argument("--at", type=float, default=0.0, metavar="T",
                   help="with --png: the --trajectory's or --task's pose at T seconds "
                   "(default 0; else all joints 0 within their limits)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--connect", metavar="ENDPOINT",
                     help="plan through a running 'arduinobot serve' at ENDPOINT "
                     "(e.g. tcp/127.0.0.1:7447)")
    src.add_argument("--local", action="store_true",
                     help="plan in this process (the default without --connect)")
    p.add_argument("--follow", action="store_true",
                   help="show the live <prefix>/joint_states of a running 'arduinobot "
                   "execute' (sim or real arm) and the kept scene as it changes, through "
                   "--connect (default tcp/127.0.0.1:7447)")
    p.add_argument("--prefix", default="arduinobot", type=key_prefix,
                   help="the service's key prefix "
                   "(its kept scene, --follow)")
    p.set_defaults(func=cmd_view)


def read_obstacles(items: list[str], scene: str | None) -> tuple[Obstacle, ...]:
    """Obstacles from --obstacle JSON strings and a --scene file.

    Raises:
        arduinobot.contract.errors.InvalidRequest: naming the bad field.
        UsageError: a file or string that is not JSON.
    """
    raw: list[tuple[object, str]] = []
    data = _scene_json(scene) if scene else None
    if scene and not is_kept_scene(data):  # a kept scene is drawn (read_kept_scene)
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


def _scene_json(path: str) -> object:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError) as e:
        raise file_problem(path, e, "--scene") from None


def is_kept_scene(data: object) -> bool:
    """Whether a --scene file is a kept scene (``scene save``'s ``{"revision",
    "objects", ...}``) rather than obstacles for each request."""
    return isinstance(data, dict) and "objects" in data


def cmd_view(ns: argparse.Namespace) -> int:
    from arduinobot.viewer import ViewerUnavailable
    from arduinobot.viewer.trajectory import PlaybackTrajectory

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
        if ns.png:
            return _write_still(ns, d, obstacles, traj, task)
        return _serve(ns, d, obstacles, traj, task)
    except ViewerUnavailable as e:
        print(f"arduinobot: {e}", file=sys.stderr)
        return EXIT_FAIL


def _read_task(path: str, d: Description) -> TaskPlayback:
    from arduinobot.planner.kinematics.chain import Kinematics
    from arduinobot.viewer.task_view import TaskPlayback
    try:
        body = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise file_problem(path, e, "--task") from None
    return TaskPlayback.from_reply(body, Kinematics(d.robot))


def _write_png(ns: argparse.Namespace, d: Description, traj: PlaybackTrajectory | None) -> int:
    from arduinobot.viewer.plots import joint_limits, plot_panels, plot_png

    if traj is None:
        raise UsageError("--plot-png needs --trajectory FILE.json or --task FILE.json")
    panels = plot_panels(traj, joint_limits(d, traj.joint_names))
    Path(ns.plot_png).write_bytes(plot_png(panels, title=str(ns.trajectory)))
    wrote(ns.plot_png, f"plots of {len(traj.times)} samples")
    return EXIT_OK


def _write_still(ns: argparse.Namespace, d: Description, obstacles: tuple[Obstacle, ...],
                 traj: PlaybackTrajectory | None, task: TaskPlayback | None) -> int:
    from arduinobot.planner.kinematics.chain import Kinematics
    from arduinobot.viewer.geometry import link_meshes
    from arduinobot.viewer.still import still_bodies, still_png

    if ns.follow:
        raise UsageError("--png draws the scene once: give --png or --follow, not both")
    scene = read_kept_scene(ns, d)
    # a task's report holds the scene it starts in (as the page shows it)
    client, served = service_scene(ns, d) if task is None else (None, None)
    if client is not None:
        client.close()
    kin = Kinematics(d.robot)
    lim = d.robot.position_limits(kin.joint_names)
    # the page's first pose: all zeros within the limits (an unbounded joint within +-pi)
    q = np.clip(np.zeros(kin.dof), np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi),
                np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi))
    if traj is not None:
        at = dict(zip(traj.joint_names, traj.at(ns.at)))
        q = np.array([at.get(n, v) for n, v in zip(kin.joint_names, q)])
    shown = scene or served
    # what a task carries at --at, where its link holds it then
    moved = {} if task is None else {
        c.object: pose for c in task.carries
        if (pose := task.object_pose(c.object, ns.at, kin)) is not None}
    bodies = still_bodies(kin, link_meshes(d, kin), q, obstacles=obstacles, scene=shown,
                          moved=moved)
    Path(ns.png).write_bytes(still_png(bodies, title=d.robot.name))
    what = f"{len(obstacles)} obstacle(s)" + (f", scene {shown.summary()}" if shown else "")
    wrote(ns.png, f"the robot and {what}")
    return EXIT_OK


def read_kept_scene(ns: argparse.Namespace, d: Description) -> ViewerScene | None:
    """The kept scene --scene names (``scene save``'s file), or None if it names none.

    Raises:
        UsageError: a kept scene with --connect or --follow (the service plans against
            and shows its own).
        arduinobot.contract.errors.InvalidRequest: an object the service would refuse.
    """
    if not ns.scene or not is_kept_scene(_scene_json(ns.scene)):
        return None
    if ns.connect or ns.follow:
        raise UsageError(f"--scene {ns.scene} is a kept scene: the service plans around "
                         "its own (drawn with --connect); `arduinobot scene load "
                         f"{ns.scene}` makes it the service's, or view it with --local")
    from arduinobot.viewer.scene_view import read_scene_file
    return read_scene_file(ns.scene, d)


def service_scene(ns: argparse.Namespace, d: Description
                  ) -> tuple[PlannerClient | None, ViewerScene | None]:
    """A session to the service and its kept scene, with --connect or --follow (else
    (None, None)). A service that does not answer is said on stderr, not fatal: the page
    plans through it once it does, and --follow draws its scene then.

    Raises:
        ServiceUnavailable: --follow and no session could be opened.
        arduinobot.contract.errors.InvalidRequest: a scene this model cannot show (a carrying link
            it does not have: view with the service's model).
    """
    endpoint = ns.connect or (DEFAULT_ENDPOINT if ns.follow else None)
    if endpoint is None:
        return None, None
    from arduinobot.client.client import PlannerClient
    from arduinobot.viewer.scene_view import ViewerScene
    try:
        client = PlannerClient(endpoint, prefix=ns.prefix)
    except ServiceUnavailable as e:
        if ns.follow:
            raise
        print(f"arduinobot view: WARN no kept scene drawn: {e}", file=sys.stderr)
        return None, None
    try:
        data = client.request("scene", timeout=10.0)
        return client, ViewerScene.from_json(data, d, source=f"{ns.prefix}/scene")
    except ServiceUnavailable as e:
        later = " (drawn once it answers: --follow)" if ns.follow else ""
        print(f"arduinobot view: WARN no kept scene drawn{later}: {e}", file=sys.stderr)
        return client, None
    except InvalidRequest as e:  # the service took it: it was made for another model
        client.close()
        raise InvalidRequest(f"{ns.prefix}/scene at {endpoint} cannot be drawn on "
                             f"'{d.robot.name}' ({e.message}): view it with the service's "
                             "model (its URDF/xacro and --package-dir)",
                             details=e.details) from None
    except BaseException:
        client.close()
        raise


def _serve(ns: argparse.Namespace, d: Description, obstacles: tuple[Obstacle, ...],
           traj: PlaybackTrajectory | None, task: TaskPlayback | None = None) -> int:
    from arduinobot.viewer.app import RobotViewer
    from arduinobot.viewer.plan_panel import PlanningPanel
    from arduinobot.viewer.planning import LocalBackend, PlanBackend, RemoteBackend
    from arduinobot.viewer.playback import PlaybackPanel

    # the remote backend first: it refuses what the service cannot plan around before a
    # page opens
    remote = (RemoteBackend(ns.connect, obstacles=obstacles, prefix=ns.prefix)
              if ns.connect else None)
    scene = read_kept_scene(ns, d)
    # a task's report holds the scene it starts in: the kept one only when following
    client, served = service_scene(ns, d) if task is None or ns.follow else (None, None)
    closers: list[Callable[[], None]] = [client.close] if client is not None else []
    try:
        page = RobotViewer(d, obstacles=obstacles, scene=scene or served, host=ns.host,
                           port=ns.port)
        closers.insert(0, page.close)
        backend: PlanBackend = remote if remote is not None else \
            LocalBackend(d, obstacles=obstacles, scene=lambda: page.scene)
        playback = PlaybackPanel(page)
        closers.insert(0, playback.close)
        PlanningPanel(page, playback, backend)
        if task is not None:
            from arduinobot.viewer.task_view import show_task
            show_task(page, playback, task)
        elif traj is not None:
            playback.load(traj, source=Path(ns.trajectory).name)
        if ns.follow:
            from arduinobot.viewer.follow import JointStateFollower
            from arduinobot.viewer.scene_follow import SceneFollower
            joints = JointStateFollower(page, ns.connect or DEFAULT_ENDPOINT, prefix=ns.prefix)
            closers.insert(0, joints.close)
            assert client is not None  # --follow opened one or raised (service_scene)
            closers.insert(0, SceneFollower(page, client).close)
        # the handlers before the ready line: a Ctrl-C right after it must stop the
        # page's threads too, not raise past them (they would keep the process alive)
        stop = threading.Event()
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
        print(f"arduinobot view: {d.robot.name} at {page.url} (Ctrl-C stops)", flush=True)
        stop.wait()
    finally:
        for close in closers:  # the followers first, the session last
            close()
    return EXIT_OK
