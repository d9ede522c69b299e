"""Paths into parsed JSON values (dicts and lists), for the fuzz tests and the fuzz bench."""

from __future__ import annotations

from typing import Any

Path = tuple[Any, ...]


def json_paths(value: Any, path: Path = ()) -> list[Path]:
    """Every path in ``value``, the root ``()`` first, depth first."""
    out = [path]
    if isinstance(value, dict):
        for k, v in value.items():
            out += json_paths(v, (*path, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out += json_paths(v, (*path, i))
    return out


def json_get(value: Any, path: Path) -> Any:
    """The value at ``path`` in ``value``."""
    for p in path:
        value = value[p]
    return value
