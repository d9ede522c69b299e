"""Package discovery and URI resolution without ROS."""

from __future__ import annotations

from pathlib import Path

import pytest

from arduinobot.description import MeshNotFound, PackageNotFound
from arduinobot.description.packages import SHIPPED_PACKAGE_DIR, build_package_index, resolve_uri


def _pkg(root: Path, folder: str, name: str) -> Path:
    d = root / folder
    d.mkdir(parents=True)
    (d / "package.xml").write_text(f"<package><name>{name}</name></package>")
    return d


def test_name_comes_from_manifest_not_folder(tmp_path):
    d = _pkg(tmp_path / "src", "folder_name", "real_name")
    idx = build_package_index([tmp_path], env={})
    assert idx.find("real_name") == d.resolve()


def test_priority_explicit_then_ros_then_ament_then_shipped(tmp_path):
    a = _pkg(tmp_path / "a", "p", "p")
    b = _pkg(tmp_path / "b", "p", "p")
    share = tmp_path / "prefix" / "share" / "p"
    share.mkdir(parents=True)
    env = {"ROS_PACKAGE_PATH": str(tmp_path / "b"), "AMENT_PREFIX_PATH": str(tmp_path / "prefix")}
    assert build_package_index([tmp_path / "a"], env=env).find("p") == a.resolve()
    assert build_package_index([], env=env).find("p") == b.resolve()
    assert build_package_index([], env={"AMENT_PREFIX_PATH": env["AMENT_PREFIX_PATH"]}).find(
        "p") == share.resolve()
    assert build_package_index([], env={}).find("arduinobot_description") == SHIPPED_PACKAGE_DIR


def test_nested_packages_are_not_searched_inside_a_package(tmp_path):
    outer = _pkg(tmp_path, "outer", "outer")
    _pkg(outer, "inner", "inner")
    idx = build_package_index([tmp_path], env={})
    assert "outer" in idx.packages and "inner" not in idx.packages


def test_resolve_uri_forms(tmp_path):
    d = _pkg(tmp_path, "p", "p")
    (d / "m.stl").write_text("x")
    idx = build_package_index([d], env={})
    assert resolve_uri("package://p/m.stl", packages=idx, base_dir=None) == d.resolve() / "m.stl"
    assert resolve_uri((d / "m.stl").as_uri(), packages=idx, base_dir=None) == d / "m.stl"
    assert resolve_uri("m.stl", packages=idx, base_dir=d) == d / "m.stl"
    with pytest.raises(PackageNotFound) as e:
        resolve_uri("package://q/m.stl", packages=idx, base_dir=None)
    assert any(str(d) in s for s in e.value.searched)
    with pytest.raises(MeshNotFound, match="case matters"):
        resolve_uri("package://p/M.STL", packages=idx, base_dir=None)


# -- the model's own package and its workspace (issue 27 item 1) ------------------------------

def _ws(tmp_path: Path) -> tuple[Path, Path, Path]:
    """A colcon workspace: src/robot_description (the model) beside src/robot_control."""
    src = tmp_path / "ws" / "src"
    own = _pkg(src, "robot_description", "robot_description")
    other = _pkg(src / "group", "robot_control", "robot_control")
    (own / "urdf").mkdir()
    model = own / "urdf" / "r.urdf.xacro"
    model.write_text("<robot/>")
    return own, other, model


def test_the_model_package_wins_for_its_own_name_with_a_warning_naming_both(tmp_path):
    own, _, model = _ws(tmp_path)
    elsewhere = _pkg(tmp_path / "opt", "robot_description", "robot_description")
    share = tmp_path / "install" / "share" / "robot_description"
    share.mkdir(parents=True)
    env = {"ROS_PACKAGE_PATH": str(tmp_path / "opt"),
           "AMENT_PREFIX_PATH": str(tmp_path / "install")}
    idx = build_package_index([elsewhere], env=env, model=model)
    assert idx.find("robot_description") == own.resolve()
    assert idx.origins["robot_description"] == "the model's package"
    assert len(idx.warnings) == 3  # --package-dir, ROS_PACKAGE_PATH, AMENT_PREFIX_PATH
    for w, copy in zip(idx.warnings, (elsewhere, elsewhere, share)):
        assert str(own.resolve()) in w and str(copy.resolve()) in w
    # without the model, the explicit folder wins as before
    assert build_package_index([elsewhere], env=env).find("robot_description") == \
        elsewhere.resolve()


def test_the_model_workspace_is_searched_after_the_environment(tmp_path):
    _, other, model = _ws(tmp_path)
    idx = build_package_index([], env={}, model=model)
    assert idx.find("robot_control") == other.resolve()
    assert idx.origins["robot_control"].startswith("the model's workspace")
    assert idx.warnings == ()
    installed = _pkg(tmp_path / "ros", "robot_control", "robot_control")
    env = {"ROS_PACKAGE_PATH": str(tmp_path / "ros")}
    assert build_package_index([], env=env, model=model).find("robot_control") == \
        installed.resolve()
    explicit = _pkg(tmp_path / "mine", "robot_control", "robot_control")
    assert build_package_index([explicit], env=env, model=model).find("robot_control") == \
        explicit.resolve()


def test_a_user_package_named_like_ours_shadows_the_shipped_one_silently(tmp_path):
    own = _pkg(tmp_path / "ws" / "src", "arduinobot_description", "arduinobot_description")
    model = own / "r.urdf"
    model.write_text("<robot/>")
    idx = build_package_index([], env={}, model=model)
    assert idx.find("arduinobot_description") == own.resolve()
    assert idx.warnings == ()
    shipped = build_package_index([], env={}, model=SHIPPED_PACKAGE_DIR / "urdf" / "x.xacro")
    assert shipped.find("arduinobot_description") == SHIPPED_PACKAGE_DIR
    assert not any("workspace" in s for s in shipped.searched)


def test_a_package_outside_src_finds_its_siblings_two_levels_deep(tmp_path):
    own = _pkg(tmp_path / "home", "bot", "bot")
    near = _pkg(tmp_path / "home" / "projects", "helper", "helper")
    _pkg(tmp_path / "home" / "a" / "b" / "c", "far", "far")
    model = own / "bot.urdf"
    model.write_text("<robot/>")
    idx = build_package_index([], env={}, model=model)
    assert idx.find("helper") == near.resolve() and "far" not in idx.packages
