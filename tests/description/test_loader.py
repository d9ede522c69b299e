"""Loading: the shipped model, a user's own package by every route, and bad input."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arduinobot.description import (
    DescriptionError,
    InvalidModel,
    MalformedXml,
    MeshNotFound,
    MissingXacroArgument,
    PackageNotFound,
    load_description,
)
from arduinobot.description.meshes import shape_mesh
from tests.helpers.user_package import PACKAGE, make_user_package

EMPTY_ENV: dict[str, str] = {}


@pytest.fixture(scope="module")
def user_pkg(tmp_path_factory) -> Path:
    return make_user_package(tmp_path_factory.mktemp("ws"))


def test_shipped_model_loads_with_srdf_tcp_and_limits():
    d = load_description(env=EMPTY_ENV)
    assert d.srdf is not None and set(d.srdf.groups) >= {"arm", "gripper"}
    assert d.srdf.groups["arm"].joints == ("joint_1", "joint_2", "joint_3")
    assert d.srdf.groups["gripper"].joints == ("joint_4", "joint_5")
    assert d.srdf.named_state("home").values == {"joint_1": 0.0, "joint_2": 0.0, "joint_3": 0.0}
    assert d.srdf.end_effectors[0].parent_link == "claw_support"
    assert d.tcp is not None and d.tcp.parent_link == "claw_support"
    assert d.tcp.source == "config/tcp.yaml"
    assert d.config.found_by == "the description package's config/"
    assert (d.default_velocity_scaling, d.default_acceleration_scaling) == (1.0, 1.0)
    assert set(d.joint_limits) == {"joint_1", "joint_2", "joint_3", "joint_4"}


def _check_user_robot(d, prefix: str = "") -> None:
    r = d.robot
    assert r.name == "my_bot"
    assert set(r.links) == {f"{prefix}base", f"{prefix}arm", f"{prefix}head"}
    assert r.actuated_joints == (f"{prefix}swing", f"{prefix}lift")
    assert r.joints[f"{prefix}lift"].type == "prismatic"
    base = shape_mesh(r.links[f"{prefix}base"].collisions[0])
    assert np.allclose(base.extents, (0.2, 0.1, 0.05))  # mm file, metres after scale
    head = shape_mesh(r.links[f"{prefix}head"].collisions[0])
    assert len(head.faces) >= 60_000
    assert np.allclose(head.extents, 0.08, atol=1e-3)
    arm = shape_mesh(r.links[f"{prefix}arm"].collisions[0])
    assert arm.bounds[0][2] == pytest.approx(0.0) and arm.bounds[1][2] == pytest.approx(0.3)
    assert d.srdf is None  # the user's package has no SRDF: nothing of ours leaks in


def test_user_package_via_package_dir(user_pkg):
    d = load_description(user_pkg / "urdf" / "my_bot.urdf.xacro", package_dirs=[user_pkg],
                         env=EMPTY_ENV)
    _check_user_robot(d)
    assert d.robot.joints["lift"].origin.xyz == (0.0, 0.0, 0.5)


def test_user_package_via_workspace_folder_and_args(user_pkg):
    d = load_description(user_pkg / "urdf" / "my_bot.urdf.xacro", package_dirs=[user_pkg.parent],
                         args={"reach": "0.7", "prefix": "l_"}, env=EMPTY_ENV)
    _check_user_robot(d, prefix="l_")
    assert d.robot.joints["l_lift"].origin.xyz == (0.0, 0.0, 0.7)


def test_user_package_via_ros_package_path(user_pkg):
    env = {"ROS_PACKAGE_PATH": str(user_pkg.parent)}
    _check_user_robot(load_description(user_pkg / "urdf" / "my_bot.urdf.xacro", env=env))


def test_user_package_via_ament_prefix_path(user_pkg, tmp_path):
    share = tmp_path / "install" / "share"
    share.mkdir(parents=True)
    os.symlink(user_pkg, share / PACKAGE)
    env = {"AMENT_PREFIX_PATH": str(tmp_path / "install")}
    _check_user_robot(load_description(user_pkg / "urdf" / "my_bot.urdf.xacro", env=env))


def test_explicit_package_dir_wins_over_shipped(tmp_path):
    # A user's own copy of arduinobot_description must shadow the shipped one.
    fake = tmp_path / "arduinobot_description"
    (fake / "urdf").mkdir(parents=True)
    (fake / "package.xml").write_text("<package><name>arduinobot_description</name></package>")
    (fake / "urdf" / "r.urdf").write_text(
        '<robot name="r"><link name="a"/><link name="b"><visual><geometry>'
        '<mesh filename="package://arduinobot_description/meshes/x.stl"/></geometry></visual>'
        '</link><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>')
    with pytest.raises(MeshNotFound) as e:
        load_description(fake / "urdf" / "r.urdf", package_dirs=[fake], env=EMPTY_ENV)
    assert str(fake) in str(e.value)


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_malformed_xml_names_file_and_line(tmp_path):
    p = _write(tmp_path, "bad.urdf", '<robot name="x"><link name="a"></robot>')
    with pytest.raises(MalformedXml) as e:
        load_description(p, env=EMPTY_ENV)
    assert str(p) in str(e.value) and "line 1" in str(e.value) and "fix:" in str(e.value)


def test_malformed_xacro(tmp_path):
    p = _write(tmp_path, "bad.urdf.xacro",
               '<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><link></robot>')
    with pytest.raises(MalformedXml) as e:
        load_description(p, env=EMPTY_ENV)
    assert str(p) in str(e.value)


def test_cycle_is_named(tmp_path):
    p = _write(tmp_path, "cycle.urdf", """<robot name="c">
      <link name="root"/><link name="a"/><link name="b"/>
      <joint name="j0" type="fixed"><parent link="root"/><child link="a"/></joint>
      <joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
      <joint name="j2" type="fixed"><parent link="b"/><child link="a"/></joint></robot>""")
    with pytest.raises(InvalidModel) as e:
        load_description(p, env=EMPTY_ENV)
    assert "joint 'j2'" in str(e.value) and "already has parent joint 'j0'" in str(e.value)


def test_pure_cycle_has_no_root(tmp_path):
    p = _write(tmp_path, "loop.urdf", """<robot name="c"><link name="a"/><link name="b"/>
      <joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
      <joint name="j2" type="fixed"><parent link="b"/><child link="a"/></joint></robot>""")
    with pytest.raises(InvalidModel, match="no root link"):
        load_description(p, env=EMPTY_ENV)


def test_dangling_link_name(tmp_path):
    p = _write(tmp_path, "dangle.urdf", """<robot name="d"><link name="a"/>
      <joint name="j" type="fixed"><parent link="a"/><child link="ghost"/></joint></robot>""")
    with pytest.raises(InvalidModel) as e:
        load_description(p, env=EMPTY_ENV)
    assert "joint 'j'" in str(e.value) and "'ghost'" in str(e.value)


def test_missing_mesh_names_link_and_path(tmp_path):
    p = _write(tmp_path, "m.urdf", """<robot name="m"><link name="a"><collision><geometry>
      <mesh filename="meshes/nothere.stl"/></geometry></collision></link></robot>""")
    with pytest.raises(MeshNotFound) as e:
        load_description(p, env=EMPTY_ENV)
    msg = str(e.value)
    assert "link 'a' <collision>" in msg and str(tmp_path / "meshes" / "nothere.stl") in msg


def test_unknown_package(tmp_path):
    p = _write(tmp_path, "u.urdf", """<robot name="u"><link name="a"><visual><geometry>
      <mesh filename="package://nobody_description/meshes/a.stl"/></geometry></visual></link>
      </robot>""")
    with pytest.raises(PackageNotFound) as e:
        load_description(p, env=EMPTY_ENV)
    assert e.value.package == "nobody_description" and "--package-dir" in str(e.value)


def test_unknown_package_in_find(tmp_path):
    p = _write(tmp_path, "f.xacro", '<robot name="f" xmlns:xacro="http://www.ros.org/wiki/xacro">'
               '<xacro:include filename="$(find nobody_description)/x.xacro"/></robot>')
    with pytest.raises(PackageNotFound) as e:
        load_description(p, env=EMPTY_ENV)
    assert e.value.package == "nobody_description"


def test_missing_xacro_argument(tmp_path):
    p = _write(tmp_path, "a.urdf.xacro", '<robot name="a" xmlns:xacro="http://www.ros.org/'
               'wiki/xacro"><link name="$(arg side)_link"/></robot>')
    with pytest.raises(MissingXacroArgument) as e:
        load_description(p, env=EMPTY_ENV)
    assert e.value.name == "side" and "--arg side=VALUE" in str(e.value)
    assert load_description(p, args={"side": "left"}, env=EMPTY_ENV).robot.root == "left_link"


def test_bad_number_names_attribute(tmp_path):
    p = _write(tmp_path, "n.urdf", """<robot name="n"><link name="a"/><link name="b"/>
      <joint name="j" type="revolute"><parent link="a"/><child link="b"/>
      <origin xyz="0 zero 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint></robot>""")
    with pytest.raises(InvalidModel) as e:
        load_description(p, env=EMPTY_ENV)
    assert "joint 'j'" in str(e.value) and 'xyz="0 zero 0"' in str(e.value)


def test_every_error_is_a_description_error():
    for cls in (InvalidModel, MalformedXml, MeshNotFound, MissingXacroArgument, PackageNotFound):
        assert issubclass(cls, DescriptionError)


@pytest.mark.parametrize("case", ["malformed", "missing_arg"])
def test_cli_reports_one_clear_line_without_traceback(tmp_path, case):
    text = {"malformed": '<robot name="x"><link name="a"></robot>',
            "missing_arg": '<robot name="a" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                           '<link name="$(arg side)"/></robot>'}[case]
    p = _write(tmp_path, "m.urdf.xacro", text)
    out = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "info", str(p)],
                         capture_output=True, text=True, cwd=Path(__file__).parents[2])
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    assert str(p) in out.stderr and "fix:" in out.stderr
