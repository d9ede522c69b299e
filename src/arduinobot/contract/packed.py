"""A trajectory's samples packed: each array as base64 of its little-endian float64 bytes.

The wire form ``trajectory.packed`` of a plan reply (``trajectory_format: "packed"``) and
of an execute request's trajectory: ``{"samples": m, "time_from_start": ..., "positions":
..., "velocities": ..., "accelerations": ..., "effort": ...}``, each array row-major. About
a third of the size of the same samples as JSON points, and read without a loop over
them: an 18 s motion of a 4-joint arm is ~130 KB packed, ~420 KB as points.

One encoder and one decoder, for the service (plan replies, the task it hands to its own
``<prefix>/execute``), the executor (execute requests) and the client (plan replies, the
trajectories it sends).
"""

from __future__ import annotations

import binascii
from collections.abc import Mapping
from typing import Any

import numpy as np
import pybase64

__all__ = ["ARRAYS", "OPTIONAL", "PackedError", "pack", "unpack"]

#: the packed arrays in their order: the times (m,), then the samples (m, dof)
ARRAYS = ("time_from_start", "positions", "velocities", "accelerations", "effort")
#: the arrays an execute request may leave out (a trajectory without efforts, say)
OPTIONAL = frozenset({"velocities", "accelerations", "effort"})


class PackedError(ValueError):
    """A packed trajectory that cannot be read: ``field`` (``trajectory.packed.<key>``)
    and the ``problem``; callers raise their own coded error from it."""

    def __init__(self, field: str, problem: str) -> None:
        super().__init__(f"{field} {problem}")
        self.field, self.problem = field, problem


def pack(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray | None = None,
         accelerations: np.ndarray | None = None, effort: np.ndarray | None = None
         ) -> dict[str, Any]:
    """``trajectory.packed`` of the times (m,) [s] and the sample arrays, each (m, dof):
    positions [rad], velocities [rad/s], accelerations [rad/s^2], effort [N m]; an array
    given as None is left out."""
    out: dict[str, Any] = {"samples": len(times)}
    for key, a in zip(ARRAYS, (times, positions, velocities, accelerations, effort)):
        if a is not None:
            raw = np.ascontiguousarray(a, dtype="<f8").tobytes()
            out[key] = pybase64.b64encode_as_string(raw)
    return out


def unpack(packed: Mapping[str, Any], width: int, *, where: str = "trajectory.packed",
           optional: frozenset[str] = frozenset()
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None,
                      np.ndarray | None]:
    """The times (m,) and the sample arrays (m, ``width``) of ``packed``, in
    :data:`ARRAYS` order; a key of ``optional`` that is absent gives None.

    Raises:
        PackedError: naming the field: no sample count, a missing array, a string that is
            not base64, not m (times) or m x width numbers, or a number that is not finite.
    """
    m = packed.get("samples")
    if isinstance(m, bool) or not isinstance(m, int) or m < 0:
        raise PackedError(f"{where}.samples", "must be the number of samples (an integer "
                          ">= 0)")
    out: list[np.ndarray | None] = []
    for key in ARRAYS:
        field = f"{where}.{key}"
        text = packed.get(key)
        if text is None and key in optional:
            out.append(None)
            continue
        if not isinstance(text, str):
            raise PackedError(field, "must be a base64 string")
        try:
            raw = pybase64.b64decode(text, validate=True)
        except (binascii.Error, ValueError):
            raise PackedError(field, "is not base64") from None
        count = m if key == "time_from_start" else m * width
        if len(raw) != 8 * count:
            raise PackedError(field, f"holds {len(raw)} bytes, not {8 * count} ({count} "
                              f"float64 for {m} samples)")
        a = np.frombuffer(raw, "<f8").astype(float)
        if not np.isfinite(a).all():
            raise PackedError(field, "holds a number that is not finite")
        out.append(a if key == "time_from_start" else a.reshape(m, width))
    times, positions = out[0], out[1]
    assert times is not None and positions is not None  # never optional
    return times, positions, out[2], out[3], out[4]
