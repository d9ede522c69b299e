"""The client library (src/arduinobot/client) stands on the contract alone: a client
install needs none of the planner, the service or the executor (issue 37). Its imports
are the standard library, the contract, its own modules and four codecs/transports.

(A rule of the package table tests/test_layers.py is to hold; kept here until merged.)"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CLIENT = ROOT / "src/arduinobot/client"
#: the third-party packages the client may import: the transport and the codecs
THIRD_PARTY = {"zenoh", "numpy", "orjson", "jsonschema_rs"}
OWN = ("arduinobot.contract", "arduinobot.client")


def _every_import(tree: ast.AST) -> set[str]:
    """Every module named by an import anywhere in ``tree``: module level, in functions,
    under ``if TYPE_CHECKING:`` (a type a client must resolve is a dependency too)."""
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, "the package imports absolutely"
            out.add(node.module or "")
    return out


def _allowed(module: str) -> bool:
    top = module.split(".")[0]
    if top == "arduinobot":
        return any(module == o or module.startswith(o + ".") for o in OWN)
    return top in sys.stdlib_module_names or top in THIRD_PARTY


def test_the_client_imports_only_the_contract_stdlib_and_its_codecs() -> None:
    files = sorted(CLIENT.rglob("*.py"))
    assert len(files) >= 5  # the scan sees the package
    bad = {str(p.relative_to(ROOT)): sorted(m for m in _every_import(ast.parse(p.read_text()))
                                            if not _allowed(m))
           for p in files}
    assert not {p: m for p, m in bad.items() if m}


def test_the_rule_refuses_what_it_should() -> None:
    # the rule itself: the planner, the service, the executor, the CLI are out
    for m in ("arduinobot.planner.timing.trajectory", "arduinobot.execution.segments",
              "arduinobot.service", "arduinobot.cli.argtypes", "arduinobot.scene", "yaml"):
        assert not _allowed(m), m
    assert _allowed("arduinobot.contract.wire") and _allowed("json")


def test_importing_the_client_loads_no_server_module() -> None:
    code = ("import sys; from arduinobot import PlannerClient; "
            "import arduinobot.client.client, arduinobot.client.replies, arduinobot.client.stream; "
            "print(' '.join(sorted(m for m in sys.modules if m.startswith('arduinobot.'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert "arduinobot.client.client" in out
    assert [m for m in out if not m.startswith(OWN)] == []
