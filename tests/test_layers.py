"""The package rules, as tables: which package of src/arduinobot may import which, the
modules some may not touch, and the harness's (tests/, bench/) own. The one AST import
walker of the tests is here; a new rule is a new row.

The floors, from the ground up (src/arduinobot/__init__.py draws them)::

    contract < scene < description < planner < execution < perception < ros2 < service
    < client < viewer < cli

A package imports only floors below it, with one narrowing: the client library imports
the contract only (a client install does not carry the server). Every import counts:
module level, inside a function, under ``TYPE_CHECKING``.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PKG = SRC / "arduinobot"

FLOORS = ("contract", "scene", "description", "planner", "execution", "perception", "ros2",
          "service",
          "client", "viewer", "cli")

#: package -> the packages it may import (besides itself): every floor below it, but the
#: client, which stands on the contract alone
MAY_IMPORT: dict[str, frozenset[str]] = {
    pkg: frozenset(FLOORS[:i]) for i, pkg in enumerate(FLOORS)
} | {"client": frozenset({"contract"})}

#: arrows today's code draws against the table, each to go when its issue's step lands:
#: (the importing file under src/arduinobot, the package it imports, why it is allowed).
#: A row whose import is gone fails the test too: delete the row then.
KNOWN_EXCEPTIONS: frozenset[tuple[str, str, str]] = frozenset({
})


@dataclass(frozen=True)
class Forbidden:
    """A narrower rule: files under ``importers`` (globs under src/arduinobot, less
    ``exempt``) import no module named in ``modules`` (or below it)."""

    rule: str
    importers: tuple[str, ...]
    modules: tuple[str, ...]
    exempt: tuple[str, ...] = ()


FORBIDDEN: tuple[Forbidden, ...] = (
    # the door into planning: MotionPlanner.solve lives in pipeline.py; a strategy gets
    # the context, never the planner, so solve cannot be reached from below it
    # (test_moving_start checks the same at run time); planner/tasks stands above the
    # door (a task is a sequence of MotionPlanner.solve calls)
    Forbidden("nothing below the door imports it", ("planner/**/*.py",),
              ("arduinobot.planner.planning.pipeline", "arduinobot.planner.MotionPlanner"),
              exempt=("planner/planning/pipeline.py", "planner/__init__.py",
                      "planner/tasks/*.py")),
    Forbidden("the viewer takes nothing of the server's internals", ("viewer/*.py",),
              ("arduinobot.service.server", "arduinobot.service.process.pool",
               "arduinobot.service.process.worker", "arduinobot.service.plan.handlers",
               "arduinobot.service.scene.sync")),
    Forbidden("no client imports the handlers",
              ("client/*.py", "cli/**/*.py", "viewer/*.py"),
              ("arduinobot.service.plan.handlers",)),
    # only `arduinobot serve` starts the server, so only it may import it
    Forbidden("only serve imports the server", ("client/*.py", "cli/**/*.py", "viewer/*.py"),
              ("arduinobot.service.server", "arduinobot.service.process.pool",
               "arduinobot.service.process.worker"),
              exempt=("cli/commands/serve.py",)),
)

#: the viewer (the optional `view` extra) is imported by the command line only inside the
#: commands that draw, never when a module is imported
VIEWER_USERS = frozenset({"cli/commands/view.py", "cli/commands/plan.py"})


# -- the walker --------------------------------------------------------------------------
def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _resolve(node: ast.ImportFrom, importer: str, is_package: bool) -> str:
    if not node.level:
        return node.module or ""
    base = importer.split(".")
    base = base[: len(base) - node.level + (1 if is_package else 0)]
    return ".".join([*base, node.module] if node.module else base)


def imports_of(path: Path, *, at_import: bool = False) -> set[str]:
    """The absolute names ``path`` imports: each module, and each ``module.name`` taken
    from it (relative imports resolved when ``path`` is under src/). With ``at_import``,
    only what importing the module runs: its module-level statements, less the ``if
    TYPE_CHECKING:`` blocks."""
    tree = ast.parse(path.read_text("utf-8"), str(path))
    inside_src = SRC in path.parents
    importer = _module_name(path) if inside_src else ""
    nodes: Iterable[ast.AST]
    if at_import:
        top = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom, ast.If, ast.Try))
               and not (isinstance(n, ast.If) and "TYPE_CHECKING" in ast.unparse(n.test))]
        nodes = (n for t in top for n in ast.walk(t))
    else:
        nodes = ast.walk(tree)
    out: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level and not inside_src:
                module = "." * node.level + (node.module or "")
            else:
                module = _resolve(node, importer, path.name == "__init__.py")
            out.add(module)
            out |= {f"{module}.{a.name}" for a in node.names}
    return out


def _is_under(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def _package_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "arduinobot" or len(parts) < 2 or parts[1] not in FLOORS:
        return None
    return parts[1]


def _sources() -> list[Path]:
    return sorted(PKG.rglob("*.py"))


def _rel(path: Path) -> str:
    return path.relative_to(PKG).as_posix()


# -- the floors --------------------------------------------------------------------------
def test_the_floors_are_every_package_and_the_table_names_only_them() -> None:
    packages = {p.name for p in PKG.iterdir() if (p / "__init__.py").exists()}
    assert packages == set(FLOORS)
    assert set(MAY_IMPORT) == set(FLOORS)
    for pkg, allowed in MAY_IMPORT.items():  # nothing may import upwards, nor itself
        assert allowed <= set(FLOORS[:FLOORS.index(pkg)]), pkg


def _arrows() -> set[tuple[str, str]]:
    """(importing file, imported package) for every import that crosses packages."""
    found = set()
    for path in _sources():
        rel = _rel(path)
        own = rel.split("/")[0]
        if own not in FLOORS:  # the root __init__: the public faces, above every floor
            continue
        for module in imports_of(path):
            other = _package_of(module)
            if other is not None and other != own:
                found.add((rel, other))
    return found


def test_every_package_imports_only_the_floors_its_row_allows() -> None:
    arrows = _arrows()
    assert len({f for f, _ in arrows}) > 50  # the scan sees the packages
    known = {(f, p) for f, p, _ in KNOWN_EXCEPTIONS}
    bad = sorted((f, p) for f, p in arrows
                 if p not in MAY_IMPORT[f.split("/")[0]] and (f, p) not in known)
    assert not bad, "imports against the floors (file, package): " + repr(bad)


def test_each_known_exception_still_happens() -> None:
    # when the step that fixes one lands, its row goes: the table stays true
    arrows = _arrows()
    stale = sorted(f"{f} -> {p} ({why})" for f, p, why in KNOWN_EXCEPTIONS
                   if (f, p) not in arrows)
    assert not stale, "fixed: delete these rows of KNOWN_EXCEPTIONS: " + "; ".join(stale)


# -- the narrower rules ------------------------------------------------------------------
def _files(globs: Iterable[str]) -> set[str]:
    return {_rel(p) for g in globs for p in PKG.glob(g)}


@pytest.mark.parametrize("rule", FORBIDDEN, ids=lambda r: r.rule)
def test_forbidden_modules(rule: Forbidden) -> None:
    files = _files(rule.importers) - _files(rule.exempt)
    assert files, rule.importers  # the globs see files
    for glob in rule.exempt:  # an exemption names files that exist
        assert _files([glob]), glob
    bad = {}
    for rel in sorted(files):
        hit = sorted(m for m in imports_of(PKG / rel)
                     if any(_is_under(m, f) for f in rule.modules))
        if hit:
            bad[rel] = hit
    assert not bad, f"{rule.rule}: {bad}"


def test_nothing_below_the_door_names_the_planner() -> None:
    # beyond imports: no module below the door refers to MotionPlanner at all
    door = next(r for r in FORBIDDEN if r.rule.startswith("nothing below the door"))
    for rel in sorted(_files(door.importers) - _files(door.exempt)):
        names = {n.id for n in ast.walk(ast.parse((PKG / rel).read_text("utf-8")))
                 if isinstance(n, ast.Name)}
        assert "MotionPlanner" not in names, rel


def test_the_command_line_imports_the_viewer_only_inside_the_commands_that_draw() -> None:
    files = sorted(PKG.joinpath("cli").rglob("*.py"))
    assert len(files) > 10  # the scan sees the package
    at_import = {_rel(p): sorted(m for m in imports_of(p, at_import=True)
                                 if _is_under(m, "arduinobot.viewer")) for p in files}
    assert not {p: m for p, m in at_import.items() if m}
    anywhere = {_rel(p) for p in files
                if any(_is_under(m, "arduinobot.viewer") for m in imports_of(p))}
    assert anywhere == VIEWER_USERS


def test_the_command_line_starts_without_the_viewer() -> None:
    # the same at run time: importing the command line loads no viewer, viser or matplotlib
    code = ("import sys\nimport arduinobot.cli.main\n"
            "print(sorted(m for m in ('arduinobot.viewer', 'viser', 'matplotlib') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


# -- the harness: tests/ and bench/ ------------------------------------------------------
BENCH = ROOT / "bench"
#: run by MPlib's or HPP's own venv as a script (they cannot import the project)
OTHER_VENV_SCRIPTS = ("mplib_runner.py", "hpp_runner.py")


def test_the_tests_import_nothing_of_bench_nor_of_a_conftest() -> None:
    # benches import the tests' launcher (tests.helpers), not the reverse; a helper is
    # imported from tests/helpers/, never from a conftest
    files = sorted((ROOT / "tests").rglob("*.py"))
    assert len(files) > 80
    for f in files:
        mods = imports_of(f)
        assert not any(_is_under(m, "bench") for m in mods), f
        assert not any("conftest" in m for m in mods), f


def test_bench_imports_no_conftest() -> None:
    files = sorted(BENCH.rglob("*.py"))
    assert len(files) > 10
    for f in files:
        assert not any("conftest" in m for m in imports_of(f)), f"{f.name}: a conftest"


@pytest.mark.parametrize("script", OTHER_VENV_SCRIPTS)
def test_no_library_module_shadows_what_the_other_venvs_script_imports(script: str) -> None:
    # started as a script, mplib_runner.py has bench/_lib first on its path: a module
    # there named like one it imports (mplib.py) is imported instead
    lib = {f.stem for f in (BENCH / "_lib").glob("*.py")}
    tops = {m.split(".")[0] for m in imports_of(BENCH / "_lib" / script)}
    assert not tops & lib, tops & lib
