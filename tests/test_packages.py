"""Package discovery and URI resolution without ROS."""

from __future__ import annotations

from pathlib import Path

import pytest

from description import MeshNotFound, PackageNotFound
from description.packages import SHIPPED_PACKAGE_DIR, build_package_index, resolve_uri


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
