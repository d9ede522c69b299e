"""`arduinobot check`: PASS on the shipped model (but the seed's inertia), FAIL on defects."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from arduinobot.description.checks import check_model
from tests.helpers.cli import run_cli
from tests.helpers.user_package import make_user_package

ROOT = Path(__file__).resolve().parents[2]


def test_shipped_model_passes_with_only_inertia_warnings():
    report = check_model(env={})
    assert not report.failed
    warns = [f for f in report.findings if f.level == "WARN"]
    assert warns and all(f.check == "inertial.plausible" for f in warns)
    # the 10 g fingers carry the seed's unit inertia: thousands of times too large
    fingers = {f.subject: f for f in warns if f.subject.startswith("gripper")}
    assert set(fingers) == {"gripper_left", "gripper_right"}
    for f in fingers.values():
        assert f.details["ratio"] > 1000
        implied = np.array(f.details["implied"])
        assert implied.shape == (3, 3) and np.allclose(implied, implied.T)
        assert np.all(np.linalg.eigvalsh(implied) > 0)


def _defective(tmp_path: Path) -> Path:
    open_box = trimesh.creation.box(extents=(1, 1, 1))
    open_box.update_faces(np.arange(len(open_box.faces) - 2))  # drop two triangles
    open_box.export(tmp_path / "open.stl")
    (tmp_path / "garbage.stl").write_bytes(b"not a mesh at all")
    (tmp_path / "r.urdf").write_text("""<robot name="r">
  <link name="base"/>
  <link name="a">
    <inertial><mass value="0"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="5"/></inertial>
    <visual><geometry><box size="1 1 1"/></geometry></visual>
    <collision><geometry><mesh filename="open.stl"/></geometry></collision>
  </link>
  <link name="b">
    <visual><geometry><mesh filename="garbage.stl"/></geometry></visual>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 0"/>
    <limit lower="1" upper="-1" effort="0" velocity="-2"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/><mimic joint="nothere"/></joint>
</robot>""")
    return tmp_path / "r.urdf"


def test_defects_are_each_reported(tmp_path):
    report = check_model(_defective(tmp_path), env={})
    assert report.failed
    fails = {(f.check, f.subject, f.message) for f in report.findings if f.level == "FAIL"}
    text = "\n".join(" | ".join(x) for x in fails)
    assert "axis is zero" in text
    assert "'nothere', which does not exist" in text
    assert any(c == "link.elements" and s == "b" and "collision" in m and "inertial" in m
               for c, s, m in fails)
    assert any(c == "inertial.mass" and s == "a" for c, s, _ in fails)
    assert any(c == "inertial.inertia" and s == "a" and "triangle inequality" in m
               for c, s, m in fails)
    # an open collision mesh is what CAD exports: a WARN (FCL, MuJoCo and Gazebo use it)
    warns = {(f.check, f.subject, f.message) for f in report.findings if f.level == "WARN"}
    assert any(c == "mesh" and s.startswith("a collision") and "not watertight" in m
               for c, s, m in warns)
    assert not any("not watertight" in m for _, _, m in fails)
    assert any(c == "mesh" and s.startswith("b visual") and "cannot read" in m
               for c, s, m in fails)
    assert any(c == "joint.limits" and s == "j1" and "lower 1.0 must be < upper -1.0" in m
               for c, s, m in fails)
    assert any(c == "joint.limits" and s == "j1" and "effort" in m for c, s, m in fails)
    assert any(c == "joint.limits" and s == "j1" and "velocity" in m for c, s, m in fails)


def test_not_positive_definite(tmp_path):
    (tmp_path / "r.urdf").write_text("""<robot name="r"><link name="base"/><link name="a">
      <inertial><mass value="1"/><inertia ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
      <visual><geometry><box size="1 1 1"/></geometry></visual>
      <collision><geometry><box size="1 1 1"/></geometry></collision></link>
      <joint name="j" type="fixed"><parent link="base"/><child link="a"/></joint></robot>""")
    report = check_model(tmp_path / "r.urdf", env={})
    assert any(f.check == "inertial.inertia" and "positive definite" in f.message
               for f in report.findings if f.level == "FAIL")


def test_load_failure_is_one_fail_line(tmp_path):
    (tmp_path / "x.urdf").write_text("<robot><link")
    report = check_model(tmp_path / "x.urdf", env={})
    assert report.failed and len(report.findings) == 1
    assert report.findings[0].check == "load" and "not well-formed" in report.findings[0].message


def test_user_package_checks_clean(tmp_path):
    pkg = make_user_package(tmp_path, fine_faces=5000)
    report = check_model(pkg / "urdf" / "my_bot.urdf.xacro", package_dirs=[pkg], env={})
    assert not report.failed, [f.line() for f in report.findings]


def test_cli_exit_codes_and_json(tmp_path):
    ok = run_cli("check")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "0 failed" in ok.stdout and "WARN  inertial.plausible gripper_right" in ok.stdout
    bad = run_cli("check", str(_defective(tmp_path)), "--json")
    assert bad.returncode == 1
    data = json.loads(bad.stdout)
    assert data["ok"] is False and data["counts"]["FAIL"] >= 7
    assert {"level", "check", "subject", "message", "details"} <= set(data["findings"][0])


def test_cli_urdf_and_info():
    urdf = run_cli("urdf")
    assert urdf.returncode == 0 and '<robot name="arduinobot">' in urdf.stdout
    assert "${" not in urdf.stdout  # fully expanded
    info = run_cli("info")
    assert info.returncode == 0
    assert "└─ base_plate  via joint_1: revolute axis (0 0 1)" in info.stdout
    assert "mimic -1*joint_4+0" in info.stdout
    assert "group arm: joint_1, joint_2, joint_3" in info.stdout


def test_cad_traits_warn_and_name_the_fix(tmp_path):
    # a millimetre mesh without scale, an open mesh, a <material> inside <geometry>
    open_box = trimesh.creation.box(extents=(300.0, 200.0, 100.0))  # [mm]
    open_box.update_faces(np.arange(len(open_box.faces) - 2))
    open_box.export(tmp_path / "part.stl")
    (tmp_path / "r.urdf").write_text("""<robot name="r"><link name="base"/><link name="a">
      <inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
      <visual><geometry><material name="grey"/><mesh filename="part.stl"/></geometry></visual>
      <collision><geometry><mesh filename="part.stl"/></geometry></collision></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="a"/>
        <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>""")
    report = check_model(tmp_path / "r.urdf", env={})
    assert not report.failed, [f.line() for f in report.findings if f.level == "FAIL"]
    warns = [f for f in report.findings if f.level == "WARN"]
    scale = [f for f in warns if f.check == "mesh.scale"]
    assert scale and all(f.details["factor"] == pytest.approx(0.001) for f in scale)
    assert 'scale="0.001 0.001 0.001"' in scale[0].message
    assert any(f.check == "parse" and "<material> inside <geometry>" in f.message for f in warns)
    assert any(f.check == "mesh" and "not watertight" in f.message for f in warns)


def test_the_shipped_models_inertia_warnings_say_why_they_are_expected(tmp_path):
    from arduinobot.description.checks import SHIPPED_INERTIA_NOTE
    warns = [f for f in check_model(env={}).findings if f.check == "inertial.plausible"]
    assert len(warns) == 6
    assert all(f.message.endswith(f"({SHIPPED_INERTIA_NOTE})") for f in warns)
    assert all(f.details["shipped_placeholder"] for f in warns)
    # a user's model with the same placeholder is not excused
    pkg = make_user_package(tmp_path, fine_faces=500)
    xacro = pkg / "urdf" / "my_bot.urdf.xacro"
    xacro.write_text(xacro.read_text().replace("${m*0.01}", "${m*100}"))
    user = [f for f in check_model(xacro, env={}).findings if f.check == "inertial.plausible"]
    assert user and not any(SHIPPED_INERTIA_NOTE in f.message for f in user)
