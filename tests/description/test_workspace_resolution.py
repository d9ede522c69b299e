"""A course user's workspace used as they would, without --package-dir (issue 27 item 1):
the package holding the model wins for its own name, its siblings in src/ are found, and
our shipped package never stands in for theirs."""

from __future__ import annotations

import os
from pathlib import Path

import trimesh

from arduinobot.description import load_description
from arduinobot.description.checks import check_model
from arduinobot.description.packages import SHIPPED_PACKAGE_DIR
from tests.helpers.cli import run_cli
from tests.helpers.course_workspace import CAMERA_MESH


def _env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if k not in ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH")}


def test_check_without_package_dir_uses_the_users_meshes(course_ws):
    r = run_cli("check", str(course_ws.xacro), env=_env())
    assert r.returncode == 0, r.stdout + r.stderr
    mesh_pass = [line for line in r.stdout.splitlines()
                 if line.startswith("PASS  mesh") and "every mesh resolves" in line]
    assert len(mesh_pass) == 1, r.stdout
    assert str(course_ws.description_pkg / "meshes") in mesh_pass[0]
    # nothing of the shipped package but the course's tasks (the workspace has none)
    shipped_tasks = str(SHIPPED_PACKAGE_DIR / "config" / "tasks.yaml")
    assert str(SHIPPED_PACKAGE_DIR) not in r.stdout.replace(shipped_tasks, "")
    # the MoveIt package beside it configures planning, as with --package-dir
    assert str(course_ws.moveit_pkg / "config" / "arduinobot.srdf") in r.stdout


def test_load_without_package_dir_resolves_every_mesh_in_the_users_package(course_ws):
    d = load_description(course_ws.xacro, env={})
    paths = {s.geometry.path for link in d.robot.links.values()
             for s in (*link.visuals, *link.collisions) if s.geometry.kind == "mesh"}
    assert paths and all(p.parent == course_ws.description_pkg / "meshes" for p in paths)
    assert course_ws.description_pkg / "meshes" / CAMERA_MESH in paths
    # a figure only the user's meshes give: millimetre files at scale 0.001 put the base
    # housing 0.946 m across, as the shipped centimetre part does at 0.01
    base = d.robot.links["base_link"].collisions[0].geometry
    m = trimesh.load(str(base.path), force="mesh")
    assert abs(m.extents[0] * base.scale[0] - 0.946) < 1e-3
    assert d.packages.origins["arduinobot_description"] == "the model's package"
    assert d.packages.origins["arduinobot_controller"].startswith("the model's workspace")
    assert d.config.moveit_package == course_ws.moveit_pkg
    assert not any("not used" in w for w in d.warnings)


def test_a_second_copy_on_the_package_path_is_not_used_and_is_named(course_ws, tmp_path):
    other = tmp_path / "other" / "arduinobot_description"
    other.mkdir(parents=True)
    (other / "package.xml").write_text("<package><name>arduinobot_description</name></package>")
    report = check_model(course_ws.xacro, package_dirs=[tmp_path / "other"], env={})
    assert not report.failed, [f.line() for f in report.findings]
    warns = [f for f in report.findings if f.check == "packages"]
    assert len(warns) == 1 and warns[0].level == "WARN"
    assert str(course_ws.description_pkg) in warns[0].message
    assert str(other) in warns[0].message


def test_a_single_file_model_named_like_ours_gets_its_own_meshes(tmp_path):
    # before: package://arduinobot_description/meshes/basement.STL silently became ours
    pkg = tmp_path / "ws" / "src" / "arduinobot_description"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "urdf").mkdir()
    (pkg / "package.xml").write_text("<package><name>arduinobot_description</name></package>")
    trimesh.creation.box(extents=(20.0, 30.0, 40.0)).export(str(pkg / "meshes" / "basement.STL"))
    model = pkg / "urdf" / "r.urdf"
    model.write_text(
        '<robot name="r"><link name="a"/><link name="b"><collision><geometry>'
        '<mesh filename="package://arduinobot_description/meshes/basement.STL" '
        'scale="0.001 0.001 0.001"/></geometry></collision></link>'
        '<joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>')
    d = load_description(model, env={})
    g = d.robot.links["b"].collisions[0].geometry
    assert g.path == (pkg / "meshes" / "basement.STL").resolve()
    assert Path(g.path).read_bytes() != (SHIPPED_PACKAGE_DIR / "meshes" / "basement.STL").read_bytes()


# -- xacro arguments as ROS users type them (issue 27 item 5) -----------------------------------

def test_arg_takes_the_ros_syntax(course_ws):
    r = run_cli("urdf", str(course_ws.xacro), "--arg", "is_sim:=false", env=_env())
    assert r.returncode == 0, r.stderr
    assert "arduinobot_controller/ArduinobotInterface" in r.stdout
    assert "GazeboSimSystem" not in r.stdout
    assert "warning" not in r.stderr


def test_an_undeclared_arg_warns_and_lists_the_declared_ones(course_ws):
    r = run_cli("urdf", str(course_ws.xacro), "--arg", "is_sm=false", env=_env())
    assert r.returncode == 0, r.stderr
    assert "GazeboSimSystem" in r.stdout  # is_sim kept its default
    assert "--arg is_sm" in r.stderr and "declared: is_sim" in r.stderr
    report = check_model(course_ws.xacro, args={"is_sm": "false"}, env={})
    warns = [f for f in report.findings if f.check == "xacro.args"]
    assert len(warns) == 1 and warns[0].level == "WARN" and "is_sim" in warns[0].message
    d = load_description(course_ws.xacro, args={"is_sm": "false"}, env={})
    assert [w for w in d.warnings if "is_sm" in w] == [warns[0].message]
