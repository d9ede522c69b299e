"""Trajectories to ros2_control's joint_trajectory_controllers over rmw_zenoh (issue 31,
item 2): ``arduinobot.ros2.controllers``, ``arduinobot.ros2.trajectory_target`` and ``arduinobot execute --ros2`` against fake controllers.

A fake controller is written from control_msgs' definition
(github.com/ros-controls/control_msgs, control_msgs/action/FollowJointTrajectory.action,
branch jazzy @ f901df2662f22a39a06aa04a85a34602c47e3cc0, 5.8.0; master @
13dacdd8748264b6cd7cbbc9893c18c90e24be00, 6.8.0) and joint_trajectory_controller's
documented behaviour (ros2_controllers' docs: a goal naming other joints than the
controller's is rejected, so is an empty one; ``~/joint_trajectory`` takes the same
trajectory as a topic; an empty trajectory on it holds the position), on our own
ActionServer over a real Zenoh session. The goal bytes it receives are also decoded by
an independent reader: a rosbags typestore built here from the upstream text.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from arduinobot.description import load_description
from arduinobot.ros2 import ControllerFailed, GoalRejected, NoController, Node
from arduinobot.ros2.actions import STATUS_CANCELED, ActionServer, GoalHandle
from arduinobot.ros2.control_msgs import FOLLOW_JOINT_TRAJECTORY, control_msgs_types
from arduinobot.ros2.controllers import (
    JOINT_TRAJECTORY,
    Controller,
    read_moveit_controllers,
    split_trajectory,
)
from arduinobot.ros2.trajectory_target import Feedback, TargetOptions, TrajectoryTarget
from tests.helpers.course_workspace import MOVEIT_CONTROLLERS_YAML
from tests.helpers.serve import REPO
from tests.ros2.test_ros2_zenoh import port, raw_session, session, wait_for  # noqa: F401

ARM = ("joint_1", "joint_2", "joint_3")
GRIPPER = ("joint_4",)

# The goal part of FollowJointTrajectory.action, verbatim (comments included) but with
# the package named on its own types, as the independent reader's rosbags parser needs.
UPSTREAM_GOAL = """# The trajectory for all revolute, continuous or prismatic joints
trajectory_msgs/JointTrajectory trajectory
# The trajectory for all planar or floating joints (i.e. individual joints with more than one DOF)
trajectory_msgs/MultiDOFJointTrajectory multi_dof_trajectory

# Tolerances applied to the joints as the trajectory is executed.  If
# violated, the goal aborts with error_code set to
# PATH_TOLERANCE_VIOLATED.
control_msgs/msg/JointTolerance[] path_tolerance
control_msgs/msg/JointComponentTolerance[] component_path_tolerance

control_msgs/msg/JointTolerance[] goal_tolerance
control_msgs/msg/JointComponentTolerance[] component_goal_tolerance
builtin_interfaces/Duration goal_time_tolerance
"""
UPSTREAM_JOINT_TOLERANCE = """string name
float64 position  # in radians or meters (for a revolute or prismatic joint, respectively)
float64 velocity  # in rad/sec or m/sec
float64 acceleration  # in rad/sec^2 or m/sec^2
"""
UPSTREAM_COMPONENT_TOLERANCE = """uint16 X_AXIS=1
uint16 Y_AXIS=2
uint16 Z_AXIS=3
uint16 TRANSLATION=4
uint16 ROTATION=5

string joint_name
uint16 component
float64 position
float64 velocity
float64 acceleration
"""


def independent_store() -> Any:
    """rosbags' Jazzy store plus control_msgs' goal and the send_goal request, from the
    upstream text: nothing of src/arduinobot/ros2/ is used."""
    store = get_typestore(Stores.ROS2_JAZZY)
    defs: dict = {}
    defs.update(get_types_from_msg(UPSTREAM_JOINT_TOLERANCE, "control_msgs/msg/JointTolerance"))
    defs.update(get_types_from_msg(UPSTREAM_COMPONENT_TOLERANCE,
                                   "control_msgs/msg/JointComponentTolerance"))
    defs.update(get_types_from_msg(UPSTREAM_GOAL, "control_msgs/msg/FJT_Goal"))
    defs.update(get_types_from_msg("unique_identifier_msgs/UUID goal_id\n"
                                   "control_msgs/msg/FJT_Goal goal",
                                   "control_msgs/msg/FJT_SendGoal_Request"))
    store.register(defs)
    return store


class FakeController:
    """A joint_trajectory_controller named ``name`` owning ``joints``, on session ``zs``.

    Accepts a goal naming exactly its joints with at least one point; plays it in real
    time (feedback every 20 ms: desired = actual = the linear interpolation); honours a
    cancel (result canceled, error_code 0); ends succeeded, or aborted with ``fail``
    (error_code, error_string). Records each send_goal request's raw bytes and each
    trajectory on ``~/joint_trajectory``.
    """

    def __init__(self, zs: zenoh.Session, name: str, joints: Sequence[str], *,
                 domain_id: int = 0, version: str = "jazzy",
                 fail: tuple[int, str] | None = None) -> None:
        self.name, self.joints, self.fail, self.version = name, tuple(joints), fail, version
        self.types = control_msgs_types(version)  # type: ignore[arg-type]
        self.raw_goals: list[bytes] = []
        self.topic_msgs: list[Any] = []
        self.handles: list[GoalHandle] = []
        real = self.types.deserialize

        def recording(data: Any, type_name: str) -> Any:
            # what arrived over Zenoh, byte for byte, for the independent reader
            if type_name == f"{FOLLOW_JOINT_TRAJECTORY}_SendGoal_Request":
                self.raw_goals.append(bytes(data))
            return real(data, type_name)
        self.types.deserialize = recording  # type: ignore[method-assign]
        self.node = Node(zs, name, domain_id=domain_id, types=self.types)
        self.server = ActionServer(self.node, f"/{name}/follow_joint_trajectory",
                                   FOLLOW_JOINT_TRAJECTORY, self._execute,
                                   on_goal=self._accept)
        self.sub = self.node.create_subscription(f"/{name}/joint_trajectory", JOINT_TRAJECTORY,
                                                 lambda m, i: self.topic_msgs.append(m))

    def _accept(self, goal: Any) -> bool:
        traj = goal.trajectory
        return sorted(traj.joint_names) == sorted(self.joints) and len(traj.points) > 0

    def _result(self, code: int, text: str) -> Any:
        return self.types.message(f"{FOLLOW_JOINT_TRAJECTORY}_Result", error_code=code,
                                  error_string=text)

    def _execute(self, handle: GoalHandle) -> None:
        self.handles.append(handle)
        t = self.types
        traj = handle.goal.trajectory
        times = np.array([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9
                          for p in traj.points])
        q = np.array([p.positions for p in traj.points])
        t0 = time.monotonic()
        while (now := time.monotonic() - t0) < times[-1]:
            if handle.cancel_requested.is_set():
                handle.canceled(self._result(0, ""))
                return
            desired = np.array([np.interp(now, times, q[:, j]) for j in range(q.shape[1])])
            point = t.message("trajectory_msgs/msg/JointTrajectoryPoint", positions=desired,
                              velocities=np.zeros(0), accelerations=np.zeros(0),
                              effort=np.zeros(0), time_from_start=t.message(
                                  "builtin_interfaces/msg/Duration", sec=int(now),
                                  nanosec=int(now % 1 * 1e9)))
            fields = t.default(f"{FOLLOW_JOINT_TRAJECTORY}_Feedback").__dict__
            fields.update(joint_names=list(traj.joint_names), desired=point, actual=point)
            handle.publish_feedback(t.message(f"{FOLLOW_JOINT_TRAJECTORY}_Feedback", **fields))
            time.sleep(0.02)
        if self.fail is not None:
            handle.abort(self._result(*self.fail))
        else:
            handle.succeed(self._result(0, ""))

    def close(self) -> None:
        self.sub.close()
        self.server.close()
        self.node.close()


@pytest.fixture(scope="module")
def plan() -> dict:
    """A real plan (reach_left, every actuated joint: the arm's three and the gripper's)."""
    from arduinobot.planner.planning.goals import NamedGoal
    from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest
    mp = MotionPlanner(load_description())
    return mp.solve(MotionRequest(goal=NamedGoal("reach_left"), seed=11)).trajectory.to_dict()


def columns(plan: dict) -> tuple[list[str], np.ndarray, dict[str, np.ndarray]]:
    pts = plan["points"]
    return (list(plan["joint_names"]), np.array([p["time_from_start"] for p in pts]),
            {k: np.array([p[k] for p in pts]) for k in ("positions", "velocities",
                                                        "accelerations")})


COURSE = (Controller("arm_controller", ARM), Controller("gripper_controller", GRIPPER))


@pytest.fixture
def controllers(session: zenoh.Session) -> Iterator[dict[str, FakeController]]:  # noqa: F811
    fakes = {c.name: FakeController(session, c.name, c.joints) for c in COURSE}
    yield fakes
    for f in fakes.values():
        f.close()


def target(session: zenoh.Session, **options: Any) -> TrajectoryTarget:  # noqa: F811
    return TrajectoryTarget(session, options=TargetOptions(**options))


def test_moveit_controllers_yaml_and_the_split() -> None:
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "moveit_controllers.yaml"
        f.write_text(MOVEIT_CONTROLLERS_YAML)  # as the MoveIt Setup Assistant writes it
        assert read_moveit_controllers(f) == COURSE
        assert COURSE[0].action == "arm_controller/follow_joint_trajectory"
    names = ["joint_4", "joint_1", "joint_2", "joint_3"]
    cols = {"positions": np.arange(8.0).reshape(2, 4),
            "velocities": np.full((2, 4), np.nan)}
    arm, grip = split_trajectory(names, [0.0, 1.0], cols, COURSE)
    assert arm.joint_names == ARM and grip.joint_names == GRIPPER
    assert arm.positions.tolist() == [[1, 2, 3], [5, 6, 7]] and grip.positions.tolist() == [[0], [4]]
    assert arm.velocities is None and arm.accelerations is None  # none in the plan: sent empty
    with pytest.raises(NoController) as e:
        split_trajectory(names + ["joint_9"], [0.0, 1.0],
                         {"positions": np.zeros((2, 5))}, COURSE)
    assert e.value.code == "ROS2_NO_CONTROLLER" and e.value.joints == ["joint_9"]
    # only the arm's joints: the gripper controller gets nothing
    assert [p.controller.name for p in split_trajectory(
        list(ARM), [0.0], {"positions": np.zeros((1, 3))}, COURSE)] == ["arm_controller"]


def test_controllers_of_the_shipped_model_follow_its_srdf_groups() -> None:
    from arduinobot.cli.ros2_execute import controllers_of
    desc = load_description()  # no moveit_controllers.yaml: <group>_controller per group
    assert controllers_of(desc, None) == COURSE
    assert controllers_of(desc, ["gripper_controller"]) == COURSE[1:]
    assert controllers_of(desc, ["my_jtc"]) == (Controller("my_jtc", ARM + GRIPPER),)


def test_controllers_of_the_course_come_from_its_moveit_controllers_yaml(
        course_ws, caplog: pytest.LogCaptureFixture) -> None:
    from arduinobot.cli.ros2_execute import controllers_of
    desc = load_description(course_ws.xacro, package_dirs=[course_ws.src],
                            moveit_config=course_ws.moveit_pkg)
    with caplog.at_level("INFO", logger="arduinobot.cli.ros2_execute"):
        assert controllers_of(desc, None) == COURSE
    yaml_file = course_ws.moveit_pkg / "config" / "moveit_controllers.yaml"
    assert f"controllers from {yaml_file}" in caplog.text


def test_control_msgs_versions_differ_in_the_feedback_only() -> None:
    jazzy, rolling = control_msgs_types("jazzy"), control_msgs_types("rolling")
    fjt = FOLLOW_JOINT_TRAJECTORY
    for same in ("_Goal", "_Result", "_SendGoal", "_GetResult"):
        assert jazzy.type_hash(fjt + same) == rolling.type_hash(fjt + same)
    for differs in ("_Feedback", "_FeedbackMessage", ""):
        assert jazzy.type_hash(fjt + differs) != rolling.type_hash(fjt + differs)
    # the tolerances' RIHS01 equal rosbags' for the upstream text (comments and all)
    ind = independent_store()
    for name in ("control_msgs/msg/JointTolerance", "control_msgs/msg/JointComponentTolerance"):
        assert jazzy.type_hash(name) == ind.hash_rihs01(name)
    assert jazzy.dds_name(fjt + "_SendGoal") == \
        "control_msgs::action::dds_::FollowJointTrajectory_SendGoal_"


def test_a_plan_split_per_controller_arrives_as_planned(session, controllers,  # noqa: F811
                                                       plan) -> None:
    names, times, cols = columns(plan)
    parts = split_trajectory(names, times, cols, COURSE)
    feedback: list[Feedback] = []
    t = target(session)
    try:
        outcomes = t.follow(parts, on_feedback=feedback.append)
    finally:
        t.close()
    assert [(o.controller, o.outcome, o.error_code) for o in outcomes] == [
        ("arm_controller", "succeeded", 0), ("gripper_controller", "succeeded", 0)]
    assert {f.controller for f in feedback} == {"arm_controller", "gripper_controller"}
    arm_fb = [f for f in feedback if f.controller == "arm_controller"]
    assert arm_fb[0].joint_names == ARM and len(arm_fb[0].desired) == 3
    ind = independent_store()
    for fake, joints in ((controllers["arm_controller"], ARM),
                         (controllers["gripper_controller"], GRIPPER)):
        assert len(fake.raw_goals) == 1
        req = ind.deserialize_cdr(fake.raw_goals[0], "control_msgs/msg/FJT_SendGoal_Request")
        traj = req.goal.trajectory
        assert tuple(traj.joint_names) == joints
        assert (traj.header.stamp.sec, traj.header.stamp.nanosec) == (0, 0)  # start on receipt
        idx = [names.index(j) for j in joints]
        assert len(traj.points) == len(plan["points"])
        for p, want in zip(traj.points, plan["points"]):
            got_t = p.time_from_start.sec + p.time_from_start.nanosec * 1e-9
            assert abs(got_t - want["time_from_start"]) < 1e-9
            for key in ("positions", "velocities", "accelerations"):
                assert list(getattr(p, key)) == [want[key][i] for i in idx]
            assert len(p.effort) == 0  # the plan's effort is for us, not a position JTC
        assert len(req.goal.path_tolerance) == 0 and req.goal.goal_time_tolerance.sec == 0


def test_cancel_stops_every_controller(session, controllers, plan) -> None:  # noqa: F811
    names, times, cols = columns(plan)
    parts = split_trajectory(names, times, cols, COURSE)
    cancel = threading.Event()
    moving: set[str] = set()

    def on_feedback(f: Feedback) -> None:
        # cancelled once every controller is executing its goal (the first feedback of
        # each), not after a fixed 0.3 s of wall clock that a loaded machine may spend
        # before the goals are even sent
        moving.add(f.controller)
        if moving == {c.name for c in COURSE}:
            cancel.set()
    t = target(session)
    try:
        outcomes = t.follow(parts, cancel=cancel, on_feedback=on_feedback)
    finally:
        t.close()
    assert cancel.is_set()
    # cancelled, not run out: each controller's goal ended CANCELED, not SUCCEEDED (no
    # wall-clock bound: on a loaded machine the follow's own end lags the trajectory's)
    assert [o.outcome for o in outcomes] == ["cancelled", "cancelled"]
    for fake in controllers.values():
        assert fake.handles[0].status == STATUS_CANCELED


def test_a_rejected_goal_is_coded_and_the_others_cancelled(session, plan) -> None:  # noqa: F811
    # the gripper controller was configured with another joint: it rejects the goal
    arm = FakeController(session, "arm_controller", ARM)
    grip = FakeController(session, "gripper_controller", ("joint_9",))
    names, times, cols = columns(plan)
    t = target(session)
    try:
        with pytest.raises(GoalRejected) as e:
            t.follow(split_trajectory(names, times, cols, COURSE))
        assert e.value.code == "ROS2_GOAL_REJECTED"
        assert e.value.details["controller"] == "gripper_controller"
        # the arm's goal, sent first, was cancelled: the arm does not move alone
        assert wait_for(lambda: bool(arm.handles) and arm.handles[0].done.is_set(), 5.0)
        assert arm.handles[0].status == STATUS_CANCELED
        assert grip.handles == []
    finally:
        t.close()
        arm.close()
        grip.close()


def test_a_controller_error_code_is_reported_with_its_error_string(session, plan  # noqa: F811
                                                                   ) -> None:
    why = "Aborted due to path tolerance violation: joint_2 off by 0.2 rad"
    arm = FakeController(session, "arm_controller", ARM, fail=(-4, why))
    grip = FakeController(session, "gripper_controller", GRIPPER)
    names, times, cols = columns(plan)
    t = target(session)
    try:
        with pytest.raises(ControllerFailed) as e:
            t.follow(split_trajectory(names, times, cols, COURSE))
    finally:
        t.close()
        arm.close()
        grip.close()
    err = e.value
    assert err.code == "ROS2_CONTROLLER_FAILED"
    assert err.details == {"controller": "arm_controller", "error_code": -4,
                           "error_name": "PATH_TOLERANCE_VIOLATED", "error_string": why}
    assert why in err.message and "aborted" in err.message


def test_auto_picks_the_controllers_control_msgs_and_feedback_arrives(session,  # noqa: F811
                                                                      plan) -> None:
    arm = FakeController(session, "arm_controller", ARM, version="rolling")
    names, times, cols = columns(plan)
    parts = split_trajectory(names[:3], times, {k: v[:, :3] for k, v in cols.items()}, COURSE)
    fb: list[Feedback] = []
    t = target(session)
    try:
        assert [o.outcome for o in t.follow(parts, on_feedback=fb.append)] == ["succeeded"]
    finally:
        t.close()
        arm.close()
    assert len(fb) >= 5  # the rolling feedback type matched: its key has the rolling hash
    fixed = FakeController(session, "arm_controller", ARM, version="rolling")
    fb.clear()
    t = target(session, control_msgs="jazzy")  # the wrong one: the motion, no feedback
    try:
        assert [o.outcome for o in t.follow(parts, on_feedback=fb.append)] == ["succeeded"]
    finally:
        t.close()
        fixed.close()
    assert fb == []


def test_the_topic_interface_and_its_hold_on_cancel(session, port, controllers,  # noqa: F811
                                                    plan) -> None:
    names, times, cols = columns(plan)
    parts = split_trajectory(names, times, cols, COURSE)
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    other = raw_session(port)  # an independent reader: raw Zenoh and rosbags
    raw: list = []
    types = control_msgs_types("jazzy")
    key = (f"0/arm_controller/joint_trajectory/{types.dds_name(JOINT_TRAJECTORY)}/"
           f"{types.type_hash(JOINT_TRAJECTORY)}")
    sub = other.declare_subscriber(key, raw.append)
    t = target(session)
    try:
        assert t.publish(parts, wait=False)
        assert wait_for(lambda: raw and all(f.topic_msgs for f in controllers.values()))
        msg = jazzy.deserialize_cdr(raw[0].payload.to_bytes(), JOINT_TRAJECTORY)
        assert tuple(msg.joint_names) == ARM and len(msg.points) == len(plan["points"])
        assert list(msg.points[-1].positions) == plan["points"][-1]["positions"][:3]
        cancel = threading.Event()
        threading.Timer(0.2, cancel.set).start()
        assert t.publish(parts, cancel=cancel) is False
        arm = controllers["arm_controller"]
        assert wait_for(lambda: len(arm.topic_msgs) == 3)
        hold = arm.topic_msgs[-1]  # an empty trajectory: joint_trajectory_controller holds
        assert tuple(hold.joint_names) == ARM and len(hold.points) == 0
    finally:
        t.close()
        sub.undeclare()
        other.close()


def run_execute(port: int, *args: str) -> subprocess.CompletedProcess:  # noqa: F811
    return subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "execute", *args, "--ros2",
                           "--connect", f"tcp/127.0.0.1:{port}"], cwd=REPO,
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, "ROS_DOMAIN_ID": "0"})


def test_execute_ros2_cli_runs_a_plan_and_codes_a_rejection(session, port, controllers,  # noqa: F811
                                                            plan, tmp_path) -> None:
    f = tmp_path / "traj.json"
    f.write_text(json.dumps({"trajectory": plan}))
    r = run_execute(port, str(f))
    assert r.returncode == 0, r.stderr
    assert "arm_controller: succeeded" in r.stdout and "gripper_controller: succeeded" in r.stdout
    assert len(controllers["arm_controller"].raw_goals) == 1
    # a goal for part of the arm's joints: joint_trajectory_controller rejects it
    part = {**plan, "joint_names": plan["joint_names"][:2],
            "points": [{k: (v[:2] if isinstance(v, list) else v) for k, v in p.items()}
                       for p in plan["points"]]}
    f.write_text(json.dumps({"trajectory": part}))
    r = run_execute(port, str(f))
    assert r.returncode == 1 and "ROS2_GOAL_REJECTED" in r.stderr, r.stderr
    assert "arm_controller rejected the goal" in r.stderr
    # joint_4 left to no controller
    f.write_text(json.dumps({"trajectory": plan}))
    r = run_execute(port, str(f), "--controller", "arm_controller")
    assert r.returncode == 1 and "ROS2_NO_CONTROLLER" in r.stderr and "joint_4" in r.stderr


def test_ros2_options_domain_from_the_environment_and_usage_errors(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from arduinobot.cli.argtypes import UsageError
    from arduinobot.cli.main import build_parser
    from arduinobot.cli.ros2_options import Ros2Settings, ros2_settings

    def settings(*argv: str) -> Ros2Settings | None:
        return ros2_settings(build_parser().parse_args(["serve", *argv]))
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    assert settings() is None
    assert settings("--ros2") == Ros2Settings(0, "/", "current")
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    assert settings("--ros2", "--ros-namespace", "/cell") == Ros2Settings(42, "/cell", "current")
    assert settings("--ros2", "--ros-domain-id", "7", "--ros2-attachment",
                    "jazzy-0.2.3") == Ros2Settings(7, "/", "jazzy-0.2.3")
    for argv, says in ((["--ros-domain-id", "3"], "--ros-domain-id goes with --ros2"),
                       (["--ros2", "--ros-domain-id", "233"], "out of 0..232"),
                       (["--ros2", "--ros-namespace", "bad//ns"], "--ros-namespace")):
        with pytest.raises(UsageError, match=says):
            settings(*argv)
    monkeypatch.setenv("ROS_DOMAIN_ID", "abc")
    with pytest.raises(UsageError, match="ROS_DOMAIN_ID"):
        settings("--ros2")


@pytest.fixture
def arm_at(session: zenoh.Session) -> Iterator[dict[str, float]]:  # noqa: F811
    """A joint_state_broadcaster: /joint_states at 50 Hz from the dict it yields (edit it to
    move the arm)."""
    from arduinobot.ros2 import open_joint_states
    robot = load_description().robot
    names = robot.actuated_joints + robot.mimic_joints
    where = dict.fromkeys(names, 0.0)
    js = open_joint_states(session, names, node_name="joint_state_broadcaster")
    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(0.02):
            js.publish([where[n] for n in names])
    th = threading.Thread(target=loop, daemon=True)
    th.start()
    yield where
    stop.set()
    th.join()
    js.close()


def test_execute_ros2_plans_from_joint_states_and_checks_the_start(
        session, port, controllers, arm_at, plan, tmp_path) -> None:  # noqa: F811
    # planned (--local) from where /joint_states says the arm is
    arm_at["joint_1"] = 0.2
    r = run_execute(port, "--named", "reach_forward", "--local")
    assert r.returncode == 0, r.stderr
    assert "arm_controller: succeeded" in r.stdout
    first = controllers["arm_controller"].handles[-1].goal.trajectory.points[0]
    assert first.positions[0] == pytest.approx(0.2, abs=1e-6)
    # a trajectory that starts elsewhere is refused before anything is sent
    f = tmp_path / "traj.json"
    f.write_text(json.dumps({"trajectory": plan}))  # starts at joint_1 = 0
    sent = len(controllers["arm_controller"].raw_goals)
    r = run_execute(port, str(f))
    assert r.returncode == 1 and "NOT_AT_START" in r.stderr and "joint_1" in r.stderr, r.stderr
    assert len(controllers["arm_controller"].raw_goals) == sent
