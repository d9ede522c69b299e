"""A trajectory's samples as CSV: the one table form the planner's trajectories and the
client's plan replies both write (``arduinobot plan --csv``)."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence

import numpy as np


def samples_csv(joint_names: Sequence[str], times: np.ndarray, *columns: np.ndarray) -> str:
    """Samples as CSV, one row each: time_from_start [s], then each joint's position
    [rad], velocity [rad/s], acceleration [rad/s²] and effort [N m] (``<joint>.position``,
    ...), from ``columns`` (m, dof) in that order; ``times`` shape (m,)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    kinds = ("position", "velocity", "acceleration", "effort")
    w.writerow(["time_from_start", *(f"{n}.{k}" for k in kinds for n in joint_names)])
    w.writerows([repr(float(x)) for x in row] for row in np.column_stack([times, *columns]))
    return buf.getvalue()
