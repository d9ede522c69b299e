"""The viewer (src/arduinobot/viewer, the optional `view` extra) stands above the client library: the core
never imports it, the rest of the client only when a command draws, and it takes nothing
of the server's internals."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CORE = tuple(f"src/arduinobot/{p}" for p in ("planner", "service", "execution", "description",
                                            "ros2", "contract", "scene", "client"))


def _imports(tree: ast.AST) -> set[str]:
    """Absolute module names imported anywhere in ``tree`` (the package of relative
    ones is not resolved: they stay inside their package)."""
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
    return out


def _top_level_imports(tree: ast.Module) -> set[str]:
    """What a module imports when it is imported: its module-level statements, but the
    ``if TYPE_CHECKING:`` blocks (never run)."""
    out: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom, ast.If, ast.Try)):
            out |= _imports(node)
    return out


def _is_viewer(module: str) -> bool:
    return module == "arduinobot.viewer" or module.startswith("arduinobot.viewer.")


def _parsed(package: str) -> dict[str, ast.Module]:
    return {str(p.relative_to(ROOT)): ast.parse(p.read_text("utf-8"))
            for p in sorted((ROOT / package).rglob("*.py"))}


def test_the_core_never_imports_the_viewer() -> None:
    bad = {path: sorted(m for m in _imports(tree) if _is_viewer(m))
           for pkg in CORE for path, tree in _parsed(pkg).items()}
    assert not {p: m for p, m in bad.items() if m}


def test_the_client_imports_the_viewer_only_inside_the_commands_that_draw() -> None:
    files = _parsed("src/arduinobot/cli")
    assert len(files) > 10  # the scan sees the package
    at_import = {p: sorted(m for m in _top_level_imports(t) if _is_viewer(m))
                 for p, t in files.items()}
    assert not {p: m for p, m in at_import.items() if m}
    anywhere = {p for p, t in files.items() if any(_is_viewer(m) for m in _imports(t))}
    assert anywhere == {"src/arduinobot/cli/commands/view.py", "src/arduinobot/cli/commands/plan.py"}


def test_the_viewer_takes_nothing_of_the_servers_internals() -> None:
    files = _parsed("src/arduinobot/viewer")
    assert "src/arduinobot/viewer/app.py" in files
    forbidden = ("arduinobot.service.server", "arduinobot.service.process.pool", "arduinobot.service.process.worker", "arduinobot.service.plan.handlers",
                 "arduinobot.service.scene.sync")
    bad = {p: sorted(m for m in _imports(t) if m.startswith(forbidden))
           for p, t in files.items()}
    assert not {p: m for p, m in bad.items() if m}


def test_the_command_line_starts_without_the_viewer() -> None:
    code = ("import sys\nimport arduinobot.cli.main\n"
            "print(sorted(m for m in ('arduinobot.viewer', 'viser', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"
