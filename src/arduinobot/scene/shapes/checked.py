"""Dimension values checked: finite numbers, lengths > 0, each error naming its field."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import SupportsFloat, SupportsIndex

from arduinobot.contract.errors import InvalidRequest


def finite_vec(value: object, n: int, field: str, *, positive: bool = False
               ) -> tuple[float, ...]:
    """``value`` as ``n`` finite floats (``positive``: each > 0), else InvalidRequest
    naming ``field``."""
    if not isinstance(value, Iterable):
        raise InvalidRequest(f"{value!r} must be {n} numbers", field=field)
    try:
        vec = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise InvalidRequest(f"{value!r} must be {n} numbers", field=field) from None
    if len(vec) != n or not all(math.isfinite(v) for v in vec):
        raise InvalidRequest(f"{value!r} must be {n} finite numbers", field=field)
    if positive and any(v <= 0 for v in vec):
        raise InvalidRequest(f"{value!r} must be > 0 [m]", field=field)
    return vec


def positive(value: object, field: str) -> float:
    """``value`` as a finite float > 0, else InvalidRequest naming ``field``."""
    if not isinstance(value, (str, SupportsFloat, SupportsIndex)):  # what float() takes
        raise InvalidRequest(f"{value!r} is not a number", field=field)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidRequest(f"{value!r} is not a number", field=field) from None
    if not math.isfinite(v) or v <= 0:
        raise InvalidRequest(f"{value!r} must be a finite number > 0 [m]", field=field)
    return v

