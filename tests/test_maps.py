"""The maps are true: every package's ``__init__`` docstring under src/arduinobot names
each of its modules and sub-packages, and every module it names as its own exists.

A module is named as ``name`` (or ``name/`` for a sub-package), or as a ``:mod:`` role
ending in it (``:mod:`.name```, ``:mod:`arduinobot.pkg.name```).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "src" / "arduinobot"
PACKAGES = sorted(p.parent for p in PKG.rglob("__init__.py"))


def _children(package: Path) -> set[str]:
    modules = {p.stem for p in package.glob("*.py")} - {"__init__", "__main__"}
    subs = {p.name for p in package.iterdir() if (p / "__init__.py").exists()}
    return modules | subs


def _dotted(package: Path) -> str:
    return ".".join(("arduinobot", *package.relative_to(PKG).parts))


def _docstring(package: Path) -> str:
    return ast.get_docstring(ast.parse((package / "__init__.py").read_text("utf-8"))) or ""


def _named(doc: str, name: str) -> bool:
    return bool(re.search(rf"``{name}/?``|:mod:`~?(?:[\w.]*\.)?{name}`", doc))


def _exists(dotted: str) -> bool:
    path = PKG.parent.joinpath(*dotted.split("."))
    return path.with_suffix(".py").exists() or path.is_dir()  # a module, a package, data


def test_the_scan_sees_every_package() -> None:
    rel = {p.relative_to(PKG).as_posix() for p in PACKAGES}
    assert {".", "planner/collision", "service/scene", "cli/commands"} <= rel


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: _dotted(p))
def test_the_package_docstring_names_each_module(package: Path) -> None:
    doc = _docstring(package)
    missing = sorted(n for n in _children(package) if not _named(doc, n))
    assert not missing, f"{_dotted(package)}'s docstring does not name: {missing}"


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: _dotted(p))
def test_every_module_the_docstring_names_exists(package: Path) -> None:
    doc, dotted = _docstring(package), _dotted(package)
    named = set()
    for ref in re.findall(r":mod:`~?([\w.]+)`", doc):  # its own: relative or under it
        if ref.startswith("."):
            named.add(f"{dotted}{ref}")
        elif ref.startswith(dotted + "."):
            named.add(ref)
    for line in re.findall(r"(?m)^- (.*?): ", doc):  # a bullet's ``name``s are its own
        named |= {f"{dotted}.{n}" for n in re.findall(r"``(\w+)/?``", line)}
    stale = sorted(n for n in named if not _exists(n))
    assert not stale, f"{dotted}'s docstring names modules that do not exist: {stale}"
