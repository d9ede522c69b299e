"""`arduinobot serve`: run the planning service on Zenoh."""

from __future__ import annotations

import argparse
import errno
import logging
import os
import re
import signal
import socket
import sys
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from arduinobot.cli.argtypes import UsageError, key_prefix, positive_int
from arduinobot.cli.common import EXIT_FAIL, EXIT_OK, add_model_args, model_options

if TYPE_CHECKING:
    from arduinobot.cli.ros2_options import Ros2Settings
    from arduinobot.description import Description
    from arduinobot.service.extension import Host


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve", help="serve planning, fk, ik and state checks over Zenoh",
        description="Open a Zenoh session and answer JSON queries on <prefix>/plan, /fk, "
        "/ik, /check, /description, /health and /schema (and the same under "
        "<prefix>/instance/<id>/ for one instance), with a liveliness token "
        "<prefix>/alive/<id>. Default: peer mode listening on tcp/127.0.0.1:7447, "
        "multicast scouting off. Behind a router: --mode client --connect ROUTER (no "
        "listener of its own). Planning runs in a pool of worker processes. Ctrl-C "
        "stops it cleanly.",
        epilog="examples:\n  arduinobot serve\n  arduinobot serve --listen tcp/0.0.0.0:7447 "
        "--workers 4\n  arduinobot serve --mode client --connect tcp/router.lan:7447\n"
        "  arduinobot serve --config zenoh.json5   # TLS, user/password, access control\n"
        "  arduinobot serve my_robot.urdf.xacro --package-dir ~/ws/src/my_robot_description\n"
        "  arduinobot serve ~/ws/src/arduinobot_description/urdf/arduinobot.urdf.xacro "
        "--package-dir ~/ws/src --moveit-config ~/ws/src/arduinobot_moveit\n"
        "  arduinobot serve --ros2 --listen tcp/127.0.0.1:7448 --connect tcp/127.0.0.1:7447"
        "   # beside rmw_zenohd")
    add_model_args(p)
    p.add_argument("--description", metavar="PATH", dest="description_path",
                   help="the robot's URDF/xacro (same as FILE)")
    p.add_argument("--listen", action="append", metavar="ENDPOINT",
                   help="an endpoint to listen on, repeatable (default tcp/127.0.0.1:7447; "
                   "with --mode client, none: it is reached through its router; with "
                   "--config, the file's)")
    p.add_argument("--connect", action="append", metavar="ENDPOINT",
                   help="a router or peer to connect to, repeatable")
    p.add_argument("--mode", choices=("peer", "client", "router"), default=None,
                   help="zenoh session mode (default peer; with --config, the file's)")
    p.add_argument("--config", metavar="FILE",
                   help="a zenoh JSON5 config file (TLS, user/password, access control); "
                   "options given here override it")
    p.add_argument("--multicast-scouting", action="store_true",
                   help="announce the service on the LAN by multicast scouting (off by "
                   "default, even with --config)")
    p.add_argument("--prefix", default="arduinobot", type=key_prefix, help="key expression prefix "
                   "(default: arduinobot)")
    p.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1, metavar="N",
                   help="planning worker processes (default: the number of cores, "
                   f"{os.cpu_count()})")
    p.add_argument("--queue", type=int, default=None, metavar="N",
                   help="requests that may wait for a worker before BUSY (default 4 per "
                   "worker)")
    p.add_argument("--timeout", type=float, default=30.0, metavar="S",
                   help="a request's deadline [s], plus planning_time for plans; then "
                   "TIMEOUT (default 30)")
    p.add_argument("--memory-cap", type=float, default=2048, metavar="MIB",
                   help="a worker's largest resident memory [MiB]; past it the worker is "
                   "killed and replaced and the request answered RESOURCE_LIMIT (default "
                   "2048; 0 for no cap)")
    p.add_argument("--cache-dir", metavar="DIR",
                   help="where to keep what is derived from the robot between starts, keyed "
                   "by content (default: $ARDUINOBOT_CACHE, else $XDG_CACHE_HOME/arduinobot, "
                   "else ~/.cache/arduinobot)")
    p.add_argument("--tasks", metavar="FILE", help="the named tasks of <prefix>/task "
                   "(default: the MoveIt config's tasks.yaml)")
    p.add_argument("--scene-file", metavar="FILE",
                   help="where this instance keeps the planning scene (arduinobot scene) "
                   "between starts (default: $ARDUINOBOT_STATE, else "
                   "$XDG_STATE_HOME/arduinobot, else ~/.local/state/arduinobot; "
                   "scene-PREFIX.json)")
    p.add_argument("--no-cache", action="store_true",
                   help="keep nothing between starts (recompute at every start)")
    from arduinobot.cli.commands.execute import add_serve_args
    from arduinobot.cli.ros2_options import add_ros2_args, add_ros2_input_args
    add_serve_args(p)
    ros = p.add_argument_group("ROS 2 (rmw_zenoh; see docs/ros2.md)")
    ros.add_argument("--ros2", action="store_true",
                     help="publish /joint_states (sensor_msgs/msg/JointState) while the "
                     "robot moves and serve the course's /task_server action "
                     "(arduinobot_msgs/action/ArduinobotTask: the named tasks by number), "
                     "as a ROS 2 node on rmw_zenoh (needs the ros2 extra). "
                     "With a ROS 2 router on 7447: --listen tcp/127.0.0.1:7448 --connect "
                     "tcp/127.0.0.1:7447")
    add_ros2_args(ros)
    add_ros2_input_args(ros)
    p.set_defaults(func=cmd_serve)


def cmd_serve(ns: argparse.Namespace) -> int:
    import zenoh

    from arduinobot.cli.commands.execute import robot_spec, ros2_settings
    from arduinobot.cli.ros2_options import ros2_inputs
    from arduinobot.contract.zconfig import DEFAULT_ENDPOINT, zenoh_message
    from arduinobot.execution.robots.base import RobotError
    from arduinobot.service.execute.execution import execute_extension
    from arduinobot.service.peers import PeerInstances
    from arduinobot.service.process.pool import PoolStartError
    from arduinobot.service.process.worker import DescriptionSpec
    from arduinobot.service.server import PlannerService, ServeOptions

    if ns.file and ns.description_path:
        raise UsageError("give the model as FILE or --description, not both")
    ros = ros2_settings(ns)
    if ros is not None and ns.no_robot:
        raise UsageError("--ros2 publishes the robot's /joint_states: not with --no-robot")
    graph = None if ros is None else _Ros2Graph(ros)
    inputs = ros2_inputs(ns, graph)  # --cloud-topic, --camera-topic
    logging.getLogger("arduinobot.service").setLevel(min(logging.INFO, logging.getLogger().level))
    if graph is not None:  # what --ros2 serves (the /task_server action, ...) is said
        logging.getLogger("arduinobot.ros2").setLevel(min(logging.INFO, logging.getLogger().level))
    spec = DescriptionSpec(path=ns.file or ns.description_path,
                           **model_options(ns),
                           cache_dir="" if ns.no_cache else ns.cache_dir)
    # a client-mode instance is reached through its router only: a listener of its own
    # would be a way around the router's TLS, passwords and access control
    listen = ns.listen if ns.listen or ns.config else \
        ([] if ns.mode == "client" else [DEFAULT_ENDPOINT])
    for endpoint in listen or ():
        # before the robot loads (seconds), not after it with Zenoh's raw bind error
        if endpoint_in_use(endpoint):
            print(f"arduinobot: serve: {endpoint} is in use (another `arduinobot serve`?); "
                  f"use --listen {_elsewhere(endpoint)}", file=sys.stderr)
            return EXIT_FAIL
    opts = ServeOptions(prefix=ns.prefix, mode=ns.mode or ("peer" if not ns.config else None),
                        listen=listen, connect=ns.connect, config_file=ns.config,
                        multicast_scouting=ns.multicast_scouting, description=spec,
                        workers=ns.workers, queue_size=ns.queue, timeout=ns.timeout,
                        memory_cap=int(ns.memory_cap * 2**20) if ns.memory_cap > 0 else None,
                        extensions=(execute_extension(robot_spec(
                            ns, progress=logging.getLogger("arduinobot.service.execute.execution").info),
                            tick_sink=None if graph is None else _joint_states(graph)),
                            *(() if graph is None else (_task_server(graph, ns.tasks),)),
                            *inputs.extensions),
                        scene_file=ns.scene_file, tasks_file=ns.tasks, camera=inputs.camera)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    svc = PlannerService(opts)
    failures: tuple[type[BaseException], ...] = (PoolStartError, PeerInstances, zenoh.ZError,
                                                 RobotError,
                                                 *_ros2_errors(ros))
    try:
        svc.start()
    except failures as e:
        print(f"arduinobot: serve: {type(e).__name__}: {zenoh_message(e)}", file=sys.stderr)
        return EXIT_FAIL
    try:
        while not stop.wait(0.5):  # short waits keep the signal handler responsive
            pass
    finally:
        logging.getLogger("arduinobot.service.server").info("shutting down")
        svc.close()
    return EXIT_OK


class _Ros2Graph:
    """The service's one ROS 2 node (``arduinobot_motion``), shared by /joint_states and
    /task_server: opened by the first that needs it, closed when both are done (one node
    name on the graph, as one rclcpp node would be)."""

    def __init__(self, ros: Ros2Settings) -> None:
        self.ros = ros
        self._node: Any = None
        self._users = 0
        self._lock = threading.Lock()

    def acquire(self, session: Any) -> Any:
        with self._lock:
            if self._node is None:
                from arduinobot.ros2 import Node
                self._node = Node(session, "arduinobot_motion", namespace=self.ros.namespace,
                                  domain_id=self.ros.domain_id,
                                  attachment=self.ros.attachment)
            self._users += 1
            return self._node

    def release(self) -> None:
        with self._lock:
            self._users -= 1
            if self._users == 0 and self._node is not None:
                self._node.close()
                self._node = None


class _Released:
    """``inner`` whose close() also releases the shared node."""

    def __init__(self, inner: Any, graph: _Ros2Graph) -> None:
        self._inner, self._graph = inner, graph

    def __call__(self, tick: Any) -> None:  # the executor's tick sink
        self._inner(tick)

    def close(self) -> None:
        try:
            self._inner.close()
        finally:
            self._graph.release()


def _joint_states(graph: _Ros2Graph) -> Callable[[Any, Description], Any]:
    """Opens ``/joint_states`` (``arduinobot.ros2.JointStates``, the executor's tick sink) on the
    service's session: the model's actuated joints, then its mimic joints."""
    def open_js(session: Any, description: Description) -> Any:
        from arduinobot import ros2
        robot = description.robot
        node = graph.acquire(session)
        try:
            js = ros2.JointStates(node, robot.actuated_joints + robot.mimic_joints)
        except BaseException:
            graph.release()
            raise
        logging.getLogger("arduinobot.service.execute.execution").info(
            "ROS 2: /joint_states on domain %d (key %s)", graph.ros.domain_id,
            js.publisher.key)
        return _Released(js, graph)
    return open_js


def _task_server(graph: _Ros2Graph, tasks_file: str | None) -> Callable[..., Any]:
    """An extension serving the course's ``/task_server`` action: the named tasks by
    number, run through ``<prefix>/task`` with execute (``arduinobot.ros2.task_server``)."""
    def make(host: Host) -> Any:
        from arduinobot.client.named_task import run_named_task
        from arduinobot.ros2.task_server import TaskServer
        from arduinobot.service.task.task_service import task_number_known

        def run(number: int, on_progress: Callable[[float], None],
                cancel: threading.Event) -> bool:
            return run_named_task(host.session, host.prefix, number,
                                  on_progress=on_progress, cancel=cancel)
        node = graph.acquire(host.session)
        try:
            server = TaskServer(node, run=run, known=lambda n: task_number_known(
                host.description, tasks_file, n))
        except BaseException:
            graph.release()
            raise
        _say_tasks(server.server.name, tasks_file, host.description)
        return _Released(server, graph)
    return make


def _say_tasks(action: str, tasks_file: str | None, description: Any) -> None:
    """Log which task numbers ``action`` runs, or warn that it rejects every goal (no
    tasks.yaml: neither ``--tasks`` nor the MoveIt config's)."""
    from pathlib import Path

    from arduinobot.description.moveit_config import read_tasks
    path = Path(tasks_file) if tasks_file else description.config.tasks
    if path is None:
        logging.getLogger("arduinobot.ros2.task_server").warning(
            "ROS 2: %s will reject every goal: robot '%s' has no tasks.yaml (give --tasks "
            "FILE, or put config/tasks.yaml in its MoveIt config; docs/tasks.md)",
            action, description.robot.name)
        return
    numbers = sorted(t.number for t in read_tasks(path).values() if t.number is not None)
    logging.getLogger("arduinobot.ros2.task_server").info(
        "ROS 2: %s runs task numbers %s from %s", action,
        ", ".join(map(str, numbers)) or "(none: every goal rejected)", path)


def _ros2_errors(ros: Ros2Settings | None) -> tuple[type[BaseException], ...]:
    """``arduinobot.ros2.Ros2Error`` when --ros2 is on (the package is not imported otherwise)."""
    if ros is None:
        return ()
    from arduinobot.ros2 import Ros2Error
    return (Ros2Error,)


def _tcp_address(endpoint: str) -> tuple[str, int] | None:
    """(host, port) of a ``tcp/HOST:PORT`` or ``tls/HOST:PORT`` endpoint (``[::1]`` for
    IPv6; Zenoh's ``?``/``#`` metadata ignored); None for other transports."""
    proto, _, rest = endpoint.partition("/")
    host, _, port = re.split(r"[?#]", rest, maxsplit=1)[0].rpartition(":")
    if proto not in ("tcp", "tls") or not host or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def endpoint_in_use(endpoint: str) -> bool:
    """Whether something already listens on ``endpoint``'s TCP address: a bind there
    fails (with SO_REUSEADDR, as Zenoh binds, so a port merely in TIME_WAIT is free).
    A name that does not resolve is left to Zenoh to refuse."""
    addr = _tcp_address(endpoint)
    if addr is None or addr[1] == 0:
        return False
    try:
        infos = socket.getaddrinfo(addr[0], addr[1], type=socket.SOCK_STREAM)
    except socket.gaierror:
        return False
    family, _, _, _, sockaddr = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(sockaddr)
        except OSError as e:
            return e.errno == errno.EADDRINUSE
    return False


def _elsewhere(endpoint: str) -> str:
    """``endpoint`` on the next free port (the suggestion for a busy one)."""
    addr = _tcp_address(endpoint)
    if addr is None:  # only a TCP or TLS endpoint can be in use: nothing to suggest
        return endpoint
    host, port = addr
    proto, shown = endpoint.partition("/")[0], f"[{host}]" if ":" in host else host
    for p in range(port + 1, min(port + 100, 65536)):
        if not endpoint_in_use(f"{proto}/{shown}:{p}"):
            return f"{proto}/{shown}:{p}"
    return f"{proto}/{shown}:PORT"
