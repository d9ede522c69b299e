"""A trajectory to play back: read from `arduinobot plan --json` output or a plan result.

Sampling between waypoints is cubic Hermite when velocities are known (the motion the
controller will follow), linear otherwise.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np


class TrajectoryFileError(ValueError):
    """A trajectory file or object is not in the `arduinobot plan --json` format."""


@dataclass(frozen=True)
class PlaybackTrajectory:
    """Waypoints of a joint trajectory.

    Attributes:
        joint_names: the joints the columns refer to.
        times: time from start of each waypoint [s], shape (n,), increasing.
        positions: [rad], shape (n, j).
        velocities: [rad/s], shape (n, j), or None.
        accelerations: [rad/s^2], shape (n, j), or None.
        effort: [N m], shape (n, j), or None.
    """

    joint_names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None = None
    accelerations: np.ndarray | None = None
    effort: np.ndarray | None = None

    @property
    def duration(self) -> float:
        """[s]"""
        return float(self.times[-1])

    def at(self, t: float) -> np.ndarray:
        """Positions at time ``t`` [s] (clamped to the trajectory), shape (j,)."""
        ts, p = self.times, self.positions
        if t <= ts[0] or len(ts) == 1:
            return p[0].copy()
        if t >= ts[-1]:
            return p[-1].copy()
        i = int(np.searchsorted(ts, t, side="right")) - 1
        h = ts[i + 1] - ts[i]
        if h <= 0:
            return p[i + 1].copy()
        s = (t - ts[i]) / h
        if self.velocities is None:
            return (1 - s) * p[i] + s * p[i + 1]
        v = self.velocities
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * p[i] + h10 * h * v[i] + h01 * p[i + 1] + h11 * h * v[i + 1]

    @classmethod
    def from_json(cls, data: object) -> PlaybackTrajectory:
        """From `arduinobot plan --json` output (``{"trajectory": {...}, ...}``) or the
        trajectory object itself (``{"joint_names": [...], "points": [...]}``).

        Raises:
            TrajectoryFileError: naming the field that is wrong.
        """
        if isinstance(data, Mapping) and "trajectory" in data:
            data = data["trajectory"]
        if not isinstance(data, Mapping):
            raise TrajectoryFileError("expected an object with 'joint_names' and 'points'")
        names = data.get("joint_names")
        points = data.get("points")
        if (not isinstance(names, Sequence) or isinstance(names, str) or not names
                or not all(isinstance(n, str) for n in names)):
            raise TrajectoryFileError("trajectory.joint_names must be a non-empty list of names")
        if not isinstance(points, Sequence) or not points:
            raise TrajectoryFileError("trajectory.points must be a non-empty list")
        j = len(names)
        cols: dict[str, list[list[float]]] = {
            "positions": [], "velocities": [], "accelerations": [], "effort": []}
        times: list[float] = []
        for k, pt in enumerate(points):
            where = f"trajectory.points[{k}]"
            if not isinstance(pt, Mapping):
                raise TrajectoryFileError(f"{where} must be an object")
            times.append(_time(pt.get("time_from_start"), f"{where}.time_from_start"))
            for key, col in cols.items():
                val = pt.get(key)
                if val is None or (key != "positions" and len(val) == 0):
                    if key == "positions":
                        raise TrajectoryFileError(f"{where}.positions is required")
                    continue
                try:
                    row = [float(x) for x in val]
                except (TypeError, ValueError):
                    raise TrajectoryFileError(f"{where}.{key} must be numbers") from None
                if len(row) != j or not all(np.isfinite(row)):
                    raise TrajectoryFileError(f"{where}.{key} must be {j} finite numbers")
                col.append(row)
        ts = np.asarray(times)
        if np.any(np.diff(ts) < 0):
            raise TrajectoryFileError("trajectory.points: time_from_start must not decrease")
        n = len(points)

        def full(key: str) -> np.ndarray | None:
            return np.asarray(cols[key]) if len(cols[key]) == n else None

        return cls(joint_names=tuple(names), times=ts, positions=np.asarray(cols["positions"]),
                   velocities=full("velocities"), accelerations=full("accelerations"),
                   effort=full("effort"))

    @classmethod
    def from_file(cls, path: str | Path) -> PlaybackTrajectory:
        """Read a JSON file (see :meth:`from_json`)."""
        try:
            data = json.loads(Path(path).read_text())
        except OSError as e:
            raise TrajectoryFileError(f"cannot read {path}: {e.strerror}") from None
        except json.JSONDecodeError as e:
            raise TrajectoryFileError(f"{path} is not JSON: {e}") from None
        return cls.from_json(data)

    @classmethod
    def from_trajectory(cls, trajectory: object) -> PlaybackTrajectory:
        """From a planner :class:`~planner.trajectory.JointTrajectory` (its sampled arrays)."""
        t = trajectory
        return cls(joint_names=tuple(t.joint_names),  # type: ignore[attr-defined]
                   times=np.asarray(t.times, float),  # type: ignore[attr-defined]
                   positions=np.asarray(t.positions, float),  # type: ignore[attr-defined]
                   velocities=np.asarray(t.velocities, float),  # type: ignore[attr-defined]
                   accelerations=np.asarray(t.accelerations, float),  # type: ignore[attr-defined]
                   effort=np.asarray(t.efforts, float))  # type: ignore[attr-defined]


def _time(value: object, field: str) -> float:
    # time_from_start is seconds, or ROS's {"sec", "nanosec"}.
    if isinstance(value, Mapping):
        try:
            return float(value.get("sec", 0)) + float(value.get("nanosec", 0)) * 1e-9
        except (TypeError, ValueError):
            raise TrajectoryFileError(f"{field} must be seconds") from None
    try:
        t = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise TrajectoryFileError(f"{field} must be a number of seconds") from None
    if not np.isfinite(t) or t < 0:
        raise TrajectoryFileError(f"{field} must be a finite number >= 0")
    return t
