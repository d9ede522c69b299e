"""LeRobot's SO-101 folder as published (tests/helpers/so101.py), as a second arm's
owner meets it: ``check``, ``info`` and ``ik`` typed as they would, and the kept scene
of another robot staying out of its world."""

from __future__ import annotations

import json
import logging
import subprocess
import sys

import numpy as np
import pytest
import zenoh

from arduinobot.contract.zconfig import zenoh_config
from arduinobot.description import load_description
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.limits import SERVO_ACCELERATION_CAP, JointLimits
from arduinobot.service.scene.sync import SceneService
from tests.helpers.serve import REPO, free_port
from tests.helpers.so101 import ARM_JOINTS, GRIPPER_JOINT, MESH_BOUNDS, make_so101


def _cli(*args: str, cwd=REPO) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "arduinobot.cli.main", *args],
                          capture_output=True, text=True, cwd=cwd, timeout=300)


@pytest.fixture(scope="module")
def so101(tmp_path_factory):
    """The folder as published: the shipped SO-101 config is found by the robot's name."""
    return make_so101(tmp_path_factory.mktemp("so101"))


@pytest.fixture(scope="module")
def bare(tmp_path_factory):
    """The same arm under a name no shipped config knows: no SRDF, no limits file."""
    return make_so101(tmp_path_factory.mktemp("bare"), name="my_arm")


def test_check_passes_a_bare_arm_with_its_massless_tool_frame_and_caps_accelerations(bare):
    r = _cli("check", bare.name, "--json", cwd=bare.parent)
    report = json.loads(r.stdout)
    fails = [f for f in report["findings"] if f["level"] == "FAIL"]
    assert r.returncode == 0 and not fails, fails
    frames = [f for f in report["findings"] if f["check"] == "link.frames"]
    assert frames and frames[0]["details"]["frames"] == ["gripper_frame_link"]
    capped = {f["subject"] for f in report["findings"] if f["check"] == "limits.acceleration"}
    assert capped == set(ARM_JOINTS) | {GRIPPER_JOINT}  # 168 to 3e5 rad/s^2 derived
    lim = JointLimits.from_description(load_description(bare, env={}))
    assert np.all(lim.acceleration == SERVO_ACCELERATION_CAP)


def test_bare_arm_tool_point_is_its_tool_frame_and_ik_leaves_the_jaw(bare):
    d = load_description(bare, env={})
    assert d.srdf is None
    assert d.tcp is not None and d.tcp.parent_link == "gripper_frame_link"
    assert d.default_group() == "arm"
    assert d.group_joints()["arm"] == list(ARM_JOINTS)
    assert d.group_joints()["gripper"] == [GRIPPER_JOINT]
    r = _cli("ik", str(bare), "--local", "--position", "0.25,0,0.1", "--json")
    assert r.returncode == 0, r.stderr
    sols = json.loads(r.stdout)["solutions"]
    assert sols, r.stdout
    kin = Kinematics(d.robot)
    names = list(kin.joint_names)
    for s in sols:
        q = np.array([s["joints"][n] if isinstance(s.get("joints"), dict) else
                      s["positions"][names.index(n)] for n in names])
        assert q[names.index(GRIPPER_JOINT)] == 0.0  # the jaw is not the arm
        tip = kin.point_position(q, "gripper_frame_link", (0.0, 0.0, 0.0))
        assert np.linalg.norm(tip - [0.25, 0, 0.1]) < 2e-3


def test_a_config_folder_beside_the_bare_urdf_is_found(tmp_path):
    urdf = make_so101(tmp_path, config=True, name="my_arm")
    r = _cli("info", urdf.name, cwd=urdf.parent)
    assert r.returncode == 0, r.stderr
    assert "config: the config/ beside the model file" in r.stdout
    assert "named state rest (arm)" in r.stdout


def test_published_folder_gets_the_shipped_so101_config(so101):
    r = _cli("check", so101.name, cwd=so101.parent)
    assert r.returncode == 0, r.stdout
    assert "FAIL" not in r.stdout and "limits.acceleration" not in r.stdout
    r = _cli("info", so101.name, cwd=so101.parent)
    assert r.returncode == 0, r.stderr
    assert "the config shipped for so101_new_calib" in r.stdout
    assert "github.com/TheRobotStudio/SO-ARM100" in r.stdout  # where the folder comes from
    assert "tcp: (-0.01, 0.0, -0.02) in gripper_frame_link" in r.stdout
    d = load_description(so101, env={})
    lim = JointLimits.from_description(d)
    assert np.all(lim.velocity <= 4.7) and np.all(lim.acceleration <= 39.0)  # an STS3215's
    assert set(d.srdf.groups) == {"arm", "gripper"}
    # the tool point is between the jaws from the SRDF's closed state (0) to open (1.5)
    # and beyond: in the fingertip frame, beyond the fixed jaw's inner face (its x = 0,
    # the jaw at x >= 0) and short of the moving jaw's nearest face, 2 cm behind the tips
    kin = Kinematics(d.robot)
    grip = list(kin.joint_names).index(GRIPPER_JOINT)
    lo, hi = MESH_BOUNDS["moving_jaw_so101_v1"]
    corners = [(x, y, z + 0.0189) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
               for z in (lo[2], hi[2])]  # the jaw's mesh sits 18.9 mm up its link
    for opening in np.linspace(0.0, 1.74, 12):
        q = np.zeros(len(kin.joint_names))
        q[grip] = opening
        frame = kin.link_pose(q, "gripper_frame_link")
        world = np.array([kin.point_position(q, "moving_jaw_so101_v1_link", c) for c in corners])
        jaw = (world - frame[:3, 3]) @ frame[:3, :3]  # into the fingertip frame
        tcp = np.linalg.inv(frame) @ np.append(kin.point_position(q, d.tcp.parent_link,
                                                                  d.tcp.xyz), 1.0)
        assert tcp[2] == pytest.approx(-0.02, abs=1e-9)
        assert jaw[:, 0].max() < tcp[0] < 0.0, (opening, jaw[:, 0].max(), tcp[0])


def _session(port: int) -> zenoh.Session:
    return zenoh.open(zenoh_config(mode="peer", listen=[f"tcp/127.0.0.1:{port}"]))


def test_kept_scene_is_per_robot_not_per_prefix(so101, tmp_path, monkeypatch, caplog):
    """The course arm's litter bin, kept under the default prefix, is not in the
    SO-101's world served under the same prefix; a scene file of another robot given
    explicitly is said to be so."""
    monkeypatch.setenv("ARDUINOBOT_STATE", str(tmp_path / "state"))
    arm = load_description(None, env={})
    arm_scene = SceneService(_session(free_port()), "arduinobot", "a",
                             tuple(arm.robot.links), description=arm)
    arm_scene.start()
    try:
        bin_ = {"id": "bin", "shape": "box", "size": [0.2, 0.2, 0.3], "xyz": [0.5, 0, 0.15]}
        reply = arm_scene.session.get("arduinobot/scene/apply",
                                      payload=json.dumps({"add": [bin_]}))
        body = json.loads(next(iter(reply)).ok.payload.to_bytes())
        assert body["revision"] == 1, body
    finally:
        arm_scene.close()
        arm_scene.session.close()
    arm_file = arm_scene.file.path
    assert json.loads(arm_file.read_text())["robot"]["name"] == "arduinobot"

    so = load_description(so101, env={})
    so_scene = SceneService(_session(free_port()), "arduinobot", "b", tuple(so.robot.links),
                            description=so)
    so_scene.start()
    try:
        assert so_scene.state.ids() == ()
        assert so_scene.file.path != arm_file
    finally:
        so_scene.close()
        so_scene.session.close()

    caplog.set_level(logging.WARNING, "arduinobot.service.scene.sync")
    told = SceneService(_session(free_port()), "arduinobot", "c", tuple(so.robot.links),
                        scene_file=arm_file, description=so)
    told.start()
    try:
        assert "another robot's kept scene" in caplog.text
        assert "'arduinobot'" in caplog.text and "'so101_new_calib'" in caplog.text
    finally:
        told.close()
        told.session.close()


def test_a_pose_goal_the_five_joints_cannot_hold_says_so_and_suggests_free_axes(so101):
    """'The gripper pointing down' with every axis held: 5 joints set the position and
    two axes; the error says so, suggests free_axes, and echoes no 16-digit quaternion.
    With the axis freed, it plans."""
    from arduinobot.contract.errors import GoalOutOfReach
    from arduinobot.service.local import LocalService

    svc = LocalService(load_description(so101, env={}))
    # the tool's z (out of the jaws) along world -z, yawed off the arm's plane: a twist
    # a yaw-pitch-pitch-pitch-roll arm cannot add at this point
    goal = {"position": [0.18, 0.08, 0.05], "orientation": {"rpy": [3.14159, 0.0, 0.3]}}
    with pytest.raises(GoalOutOfReach) as e:
        svc.request("plan", {"goal": goal, "seed": 1})
    msg = e.value.message
    assert "5 joints" in msg and "free_axes" in msg and "at most 2" in msg, msg
    assert e.value.details["orientation_dof"] == 2
    assert not any(len(t) > 8 for t in msg.replace(",", " ").replace("]", " ").split()
                   if t.lstrip("-[").replace(".", "").isdigit()), msg
    free = e.value.details["suggest_free_axes"]
    assert len(free) == 1
    reply = svc.request("plan", {"goal": {**goal, "free_axes": free}, "seed": 1})
    assert reply["verification"]["ok"], reply["verification"]


def test_in_process_work_keeps_and_reads_the_artifact_cache(so101, tmp_path):
    """`check-state --local` builds the model's geometry into the user's artifact cache
    (the one `serve` reads), so the next in-process command reads it."""
    import os
    env = {**os.environ, "ARDUINOBOT_CACHE": str(tmp_path / "cache")}
    args = [sys.executable, "-m", "arduinobot.cli.main", "check-state", so101.name, "--local",
            "--joints", "0,0,0,0,0,0"]
    r = subprocess.run(args, capture_output=True, text=True, cwd=so101.parent, env=env,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    kept = sorted(p.relative_to(tmp_path / "cache") for p in (tmp_path / "cache").rglob("*.npz"))
    assert kept, "nothing kept in the artifact cache"
    stamps = {p: (tmp_path / "cache" / p).stat().st_mtime_ns for p in kept}
    r = subprocess.run(args, capture_output=True, text=True, cwd=so101.parent, env=env,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    # read, not rebuilt: the same files, untouched
    assert {p: (tmp_path / "cache" / p).stat().st_mtime_ns for p in kept} == stamps


def test_srdf_output_for_a_bare_arm_writes_groups_end_effector_and_a_home_state(bare,
                                                                                 tmp_path):
    out = tmp_path / "my_arm.srdf"
    r = _cli("srdf", str(bare), "--samples", "100", "--output", str(out))
    assert r.returncode == 0, r.stderr
    d = load_description(bare, env={}, srdf=out)
    srdf = d.srdf
    assert srdf is not None
    assert srdf.groups["arm"].joints == ARM_JOINTS
    assert srdf.groups["gripper"].joints == (GRIPPER_JOINT,)
    (eff,) = srdf.end_effectors
    assert (eff.parent_link, eff.group, eff.parent_group) == ("gripper_frame_link", "gripper",
                                                              "arm")
    assert srdf.named_state("home", "arm").values == dict.fromkeys(ARM_JOINTS, 0.0)
    assert any(p.reason == "Adjacent" for p in srdf.disabled_collisions)
    # the service reads it as the owner's: same tool point, arm the default group
    assert d.tcp is not None and d.tcp.parent_link == "gripper_frame_link"
    assert d.default_group() == "arm"


@pytest.mark.slow
def test_ready_line_does_not_claim_a_connection_nothing_answers(tmp_path):
    """serve --connect to a port where nothing listens: the ready line says so instead
    of 'connected to' (issue 38, item 7)."""
    from tests.helpers.serve import start_server
    nobody = f"tcp/127.0.0.1:{free_port()}"
    srv = start_server(["--workers", "1", "--connect", nobody,
                        "--cache-dir", str(tmp_path / "cache")], timeout=240)
    try:
        assert "connected to" not in srv.ready_line
        assert f"connecting to {nobody} (nothing answers there yet" in srv.ready_line
    finally:
        srv.stop()


def test_tcp_yaml_rpy_turns_the_tool_frame_pose_goals_use(tmp_path):
    """An owner's tcp.yaml turning the tool frame 90 deg about its z: a pose goal is of
    that frame (issue 38, item 3), read from the config/ beside the bare URDF."""
    from arduinobot.description.model import rpy_matrix
    from arduinobot.planner.kinematics.rotations import quaternion_of_matrix
    from arduinobot.service.local import LocalService

    urdf = make_so101(tmp_path, config=True, name="my_arm")
    (urdf.parent / "config" / "tcp.yaml").write_text(
        "tcp:\n  parent_link: gripper_frame_link\n  xyz: [0.0, 0.0, 0.0]\n"
        "  rpy: [0.0, 0.0, 1.5707963267948966]\n")
    d = load_description(urdf, env={})
    assert d.tcp is not None and d.tcp.rpy[2] == pytest.approx(np.pi / 2)
    kin = Kinematics(d.robot)
    names = list(kin.joint_names)
    q = np.zeros(len(names))
    q[[names.index(n) for n in ARM_JOINTS]] = [0.2, -0.5, 0.5, 1.0, 0.3]
    link = kin.link_pose(q, "gripper_frame_link")
    turn = rpy_matrix((0.0, 0.0, np.pi / 2))
    goal = {"position": [float(v) for v in link[:3, 3]],
            "orientation": {"quaternion": [float(v) for v in
                                           quaternion_of_matrix(link[:3, :3] @ turn)]}}
    reply = LocalService(d).request("plan", {"goal": goal, "seed": 2})
    end = np.array(reply["trajectory"]["points"][-1]["positions"], float)
    full = np.array([end[reply["trajectory"]["joint_names"].index(n)] for n in names])
    got = kin.link_pose(full, "gripper_frame_link")
    # the tool frame (the link's turned by rpy) is at the goal, not the link's own
    np.testing.assert_allclose(got[:3, :3] @ turn, link[:3, :3] @ turn, atol=2e-3)
    np.testing.assert_allclose(got[:3, 3], link[:3, 3], atol=1e-3)


def test_output_into_a_closed_pipe_ends_quietly(so101):
    """`arduinobot info | head` with the reader gone first: no BrokenPipeError
    traceback, the exit a C tool killed by SIGPIPE gives (issue 38, item 9)."""
    proc = subprocess.Popen([sys.executable, "-m", "arduinobot.cli.main", "info", so101.name],
                            cwd=so101.parent, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader is gone before anything is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 141, err
    assert "BrokenPipeError" not in err and "Traceback" not in err, err
