"""bench/ is a harness: entry scripts at its top level (each ending with one JSON line that
names it), shared pieces in bench/_lib, no sys.path tricks. Its import rules (the tests
import none of it, it imports no conftest, nothing in bench/_lib shadows what the other
venv's script imports) are rows of tests/test_layers.py."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

from tests.helpers.procs import REPO

BENCH = REPO / "bench"
ENTRY = sorted(f for f in BENCH.glob("*.py") if not f.name.startswith("_"))
LIB = sorted((BENCH / "_lib").glob("*.py"))
#: run by MPlib's or HPP's own venv as a script (they cannot import the project)
OTHER_VENV_SCRIPTS = {"mplib_runner.py", "mplib_cloud.py", "hpp_runner.py"}


def _tree(f: Path) -> ast.Module:
    return ast.parse(f.read_text(), str(f))


def _has_main_block(tree: ast.Module) -> bool:
    return any(isinstance(n, ast.If) and "__main__" in ast.unparse(n.test) for n in tree.body)


def test_every_entry_script_runs_as_main_and_ends_with_its_named_json_line():
    assert len(ENTRY) >= 10, ENTRY
    for f in ENTRY:
        tree = _tree(f)
        assert ast.get_docstring(tree), f"{f.name}: no docstring (./dev bench lists it)"
        assert _has_main_block(tree), f"{f.name}: not an entry script"
        emits = [n for n in ast.walk(tree) if isinstance(n, ast.Call)
                 and ast.unparse(n.func) == "emit"]
        assert len(emits) == 1, f"{f.name}: {len(emits)} calls of emit()"
        name = emits[0].args[0]
        assert isinstance(name, ast.Constant) and name.value == f.stem, \
            f"{f.name}: emit({ast.unparse(name)}, ...) does not name it"


def test_library_modules_are_not_entry_scripts():
    assert LIB, "bench/_lib is empty"
    for f in LIB:
        if f.name in OTHER_VENV_SCRIPTS:
            continue
        assert not _has_main_block(_tree(f)), f"{f.name} is a script: move it up to bench/"


def test_no_sys_path_tricks_in_bench():
    for f in [*ENTRY, *LIB]:
        assert "sys.path" not in f.read_text(), f"{f.name} changes sys.path"


def test_dev_bench_without_a_known_name_lists_the_entry_scripts():
    for argv in ([], ["recheck"]):  # recheck is a library module now, not a benchmark
        r = subprocess.run([sys.executable, "-m", "bench", *argv], cwd=REPO,
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 2, r.stderr
        listed = [ln.split()[0] for ln in r.stderr.splitlines() if ln.startswith("  ")]
        assert listed == [f.stem for f in ENTRY], r.stderr
