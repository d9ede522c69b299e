"""One registry of error codes (src/arduinobot/contract/codes.py): every layer's codes come from it.

Fails if the planner's exceptions, the service's replies (any code-like string in
src/arduinobot/service/ or src/arduinobot/client/), src/arduinobot/contract/schema/error.json, the error table of docs/service.md or
the client's exception classes drift from :class:`arduinobot.contract.codes.Code`.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import arduinobot.client.errors as cerr
import arduinobot.contract.errors as perr
from arduinobot.contract.codes import EXECUTION_CODES, PLAN_SERVICE_CODES, Code

ROOT = Path(__file__).resolve().parents[2]

# Upper-case string constants in src/arduinobot/service/ and src/arduinobot/client/ that are not error codes.
NOT_CODES = frozenset({
    # structure caps named in an error's details.cap (src/arduinobot/contract/caps.py, plan_io.py)
    "MAX_DEPTH", "MAX_ITEMS", "MAX_ELEMENTS", "MAX_STRING", "MAX_SAMPLES",
    # environment and sysconf names, __all__ entries
    "ARDUINOBOT_CACHE", "ARDUINOBOT_MEMTRACE", "ARDUINOBOT_MEMTRACE_TRIM", "XDG_CACHE_HOME",
    "ARDUINOBOT_MALLOC_TRIM",
    "ARDUINOBOT_HOPTRACE", "SC_PAGE_SIZE", "MAX_PAYLOAD", "MAX_EXECUTE_PAYLOAD", "SCHEMA_NAMES",
    "ARRAYS", "OPTIONAL", "RANGES", "JSON",
    "INSTALL_HINT",
    # the model's file format, named in `arduinobot limits` (src/arduinobot/planner/kinematics/applied_limits.py)
    "URDF",
    # the kept scene (src/arduinobot/scene/state.py): its state folder and its object cap
    "ARDUINOBOT_STATE", "XDG_STATE_HOME", "MAX_SCENE_OBJECTS", "MAX_SCENE_MESH_BYTES",
    # `arduinobot check` outcomes (printed, never on the wire)
    "PASS", "WARN", "FAIL", "FAILED",
})
_CODE_LIKE = re.compile(r"^[A-Z][A-Z0-9_]{2,}$")


def _all_subclasses(cls: type) -> list[type]:
    out = []
    for sub in cls.__subclasses__():
        out += [sub, *_all_subclasses(sub)]
    return out


def _code_like_strings(folder: str) -> dict[str, list[str]]:
    """Every upper-case string constant in ``folder``'s Python files (argparse metavars
    aside) -> where it occurs."""
    found: dict[str, list[str]] = {}
    for path in sorted((ROOT / folder).rglob("*.py")):
        tree = ast.parse(path.read_text("utf-8"))
        metavars = {id(k.value) for k in ast.walk(tree)
                    if isinstance(k, ast.keyword) and k.arg == "metavar"}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Constant) and isinstance(node.value, str)
                    and _CODE_LIKE.match(node.value) and id(node) not in metavars):
                found.setdefault(node.value, []).append(
                    f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def test_registry_is_its_own_strings() -> None:
    assert all(c.value == c.name for c in Code)
    assert set(PLAN_SERVICE_CODES) <= set(Code)
    assert len(set(PLAN_SERVICE_CODES)) == len(PLAN_SERVICE_CODES)


def test_planner_exceptions_use_registry_codes() -> None:
    classes = [perr.PlanningError, *_all_subclasses(perr.PlanningError)]
    codes = {c.code for c in classes}
    assert all(isinstance(c.code, Code) for c in classes), classes
    assert codes <= set(PLAN_SERVICE_CODES), codes - set(PLAN_SERVICE_CODES)


def test_error_schema_enum_is_the_registry() -> None:
    schema = json.loads((ROOT / "src/arduinobot/contract/schema/error.json").read_text("utf-8"))
    enum = schema["properties"]["error"]["properties"]["code"]["enum"]
    assert enum == [c.value for c in PLAN_SERVICE_CODES]


def _table_codes(text: str) -> list[str]:
    rows = re.findall(r"^\| (`[A-Z_]+`(?: / `[A-Z_]+`)*) \|", text, flags=re.M)
    return [c for row in rows for c in re.findall(r"`([A-Z_]+)`", row)]


def test_documented_error_table_is_the_registry() -> None:
    """docs/service.md's two tables: the planning service's codes, then execution's and
    the drivers'; together every code but the client's own."""
    text = (ROOT / "docs" / "service.md").read_text("utf-8")
    plan, _, execution = text.partition("### Execution and driver errors")
    assert execution, "docs/service.md lost its execution errors table"
    assert sorted(_table_codes(plan)) == sorted(c.value for c in PLAN_SERVICE_CODES)
    assert _table_codes(execution) == [c.value for c in EXECUTION_CODES]
    client_own = {Code.UNAVAILABLE, Code.UNKNOWN}
    assert set(Code) == set(PLAN_SERVICE_CODES) | set(EXECUTION_CODES) | client_own


def test_client_exceptions_cover_every_service_code() -> None:
    assert set(cerr.ERRORS) == set(PLAN_SERVICE_CODES)
    for code, cls in cerr.ERRORS.items():
        assert cls.code == code
        err = cerr.error_from_reply({"error": {"code": str(code), "message": "m",
                                               "details": {}}})
        assert type(err) is cls and err.code == code
    classes = [cerr.ServiceError, *_all_subclasses(cerr.ServiceError)]
    assert {c.code for c in classes} <= set(Code)


def test_planner_error_reaches_the_client_as_its_class() -> None:
    """The same name on both sides: a planner exception's code picks the client class."""
    for cls in _all_subclasses(perr.PlanningError):
        client_cls = cerr.ERRORS[cls.code]
        assert client_cls.code == cls.code


def test_every_code_string_in_service_and_clients_is_registered() -> None:
    found: dict[str, list[str]] = {}
    for pkg in ("service", "client", "cli", "viewer", "execution", "contract", "scene"):
        found |= _code_like_strings(f"src/arduinobot/{pkg}")
    unknown = {s: where for s, where in found.items()
               if s not in NOT_CODES and s not in set(Code)}
    assert not unknown, f"codes not in src/arduinobot/contract/codes.py (add them there): {unknown}"


def test_the_scan_sees_codes() -> None:
    """The scan above is not vacuous: upper-case constants in src/arduinobot/service/ are seen (the
    pool's codes are no longer hand-written strings: it takes them from Code)."""
    found = _code_like_strings("src/arduinobot/service")
    found |= _code_like_strings("src/arduinobot/contract")
    assert "MAX_DEPTH" in found and "ARDUINOBOT_CACHE" in found
