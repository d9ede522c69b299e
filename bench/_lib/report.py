"""The last line of every benchmark: one line of JSON that names the benchmark."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any


def emit(bench: str, figures: Mapping[str, Any]) -> None:
    """Print ``{"bench": bench, **figures}`` as one line (numpy scalars as floats)."""
    print(json.dumps({"bench": bench, **figures}, default=float), flush=True)
