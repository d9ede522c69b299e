"""A trajectory to play back: read from `arduinobot plan --json` output or a plan result.

Sampling between waypoints is cubic Hermite when velocities are known (the motion the
controller will follow), linear otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from arduinobot.execution.segments import InvalidTrajectory, parse_trajectory, read_json

#: the viewer's name for a file or object not in the `arduinobot plan --json` format
TrajectoryFileError = InvalidTrajectory


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
        """From `arduinobot plan --json` output or the trajectory object itself
        (:func:`~arduinobot.execution.segments.parse_trajectory`); an optional column that
        some point lacks is left out.

        Raises:
            TrajectoryFileError: naming the field that is wrong.
        """
        names, times, cols = parse_trajectory(data)

        def optional(kind: str) -> np.ndarray | None:
            c = cols[kind]
            return None if np.isnan(c).any() else c

        # positions: parse_trajectory requires them at every point
        return cls(names, times, cols["positions"], velocities=optional("velocities"),
                   accelerations=optional("accelerations"), effort=optional("effort"))

    @classmethod
    def from_file(cls, path: str | Path) -> PlaybackTrajectory:
        """Read a JSON file (see :meth:`from_json`)."""
        return cls.from_json(read_json(path))
