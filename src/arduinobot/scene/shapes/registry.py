"""The registry of shape kinds by their JSON ``shape`` name."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.shapes.base import S, Shape

_SHAPES: dict[str, type[Shape]] = {}
_DIMENSIONS: list[frozenset[str]] = [frozenset()]  # every shape's fields, kept by register


def register(cls: type[S]) -> type[S]:
    """Add a shape class to the registry under its ``kind`` (a class decorator)."""
    if cls.kind in _SHAPES:
        raise ValueError(f"shape kind '{cls.kind}' is registered twice")
    _SHAPES[cls.kind] = cls
    _DIMENSIONS[0] = _DIMENSIONS[0] | set(cls.field_names())
    return cls


def kinds() -> tuple[str, ...]:
    """Every registered shape name, in registration order."""
    return tuple(_SHAPES)


def shape_class(kind: object, *, field: str = "shape") -> type[Shape]:
    """The class registered under ``kind``, else InvalidRequest naming ``field``."""
    cls = _SHAPES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise InvalidRequest(f"'{kind}' is not one of {', '.join(_SHAPES)}", field=field)
    return cls


def dimension_fields() -> frozenset[str]:
    """Every dimension field of any registered shape."""
    return _DIMENSIONS[0]


def check_inline(cls: type[Shape], data: Mapping[str, Any], *, where: str) -> None:
    """Refuse an inline field (:attr:`Shape.inline`) that ``cls`` does not take."""
    for key in sorted({k for c in _SHAPES.values() for k in c.inline} - set(cls.inline)):
        if key in data:
            owners = " or ".join(c.kind for c in _SHAPES.values() if key in c.inline)
            raise InvalidRequest(f"only a {owners} object takes it", field=f"{where}.{key}")

