"""One table of the ranges a request's numbers must lie in.

The planner validates against it, the trajectory sampler and the executor check rates
with it, the Python client pre-checks with it, and ``tests/contract/test_ranges.py`` holds it equal
to the JSON schemas in ``src/arduinobot/contract/schema/``, so the five places that once each wrote
"(0, 60] s" and "[1, 1000] Hz" cannot drift apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from arduinobot.contract.errors import InvalidRequest

__all__ = ["Range", "RANGES", "check_range"]

RangeName = Literal["planning_time", "velocity_scaling", "acceleration_scaling",
                    "sample_rate", "blend_lead"]


@dataclass(frozen=True)
class Range:
    """A closed or half-open interval of a request field, in ``unit``."""

    lo: float
    hi: float
    unit: str
    open_lo: bool = False

    def __contains__(self, value: object) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        v = float(value)
        return math.isfinite(v) and (v > self.lo if self.open_lo else v >= self.lo) \
            and v <= self.hi

    def __str__(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"{'(' if self.open_lo else '['}{self.lo:g}, {self.hi:g}]{unit}"


RANGES: dict[str, Range] = {
    "planning_time": Range(0.0, 60.0, "s", open_lo=True),
    # floored at 0.01, not open at 0: a scaling of 1e-300 failed inside ruckig
    "velocity_scaling": Range(0.01, 1.0, ""),
    "acceleration_scaling": Range(0.01, 1.0, ""),
    "sample_rate": Range(1.0, 1000.0, "Hz"),
    # a blend is planned while the arm moves on: the lead must cover the planning
    "blend_lead": Range(0.05, 30.0, "s"),
}


def check_range(value: object, name: RangeName, *, field: str | None = None) -> float:
    """``value`` as a float if it lies in ``RANGES[name]``.

    Raises:
        InvalidRequest: (field ``field`` or ``name``) not a finite number, or outside.
    """
    rng = RANGES[name]
    where = field or name
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(float(value)):
        raise InvalidRequest(f"{value!r} is not a finite number", field=where)
    if value not in rng:
        raise InvalidRequest(f"{float(value)!r} must be in {rng}", field=where)
    return float(value)
