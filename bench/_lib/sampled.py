"""Positions between the samples of a trajectory received over the wire (benchmarks only).

A plan reply carries samples (time, position, velocity, acceleration per joint, 100 Hz by
default), not the continuous motion. ``SampledPositions`` interpolates each interval with
the quintic Hermite polynomial matching position, velocity and acceleration at both of its
ends. It reproduces any polynomial of degree <= 5 exactly, so on the jerk-limited
trajectories (piecewise cubic in time along their path) it differs from the motion only
in the few intervals holding a switch, by O(jerk * dt^3) -- well under the 0.002 rad
collision step of the re-check. Limits re-derived from it by finite differences (bench/_lib/
recheck.py) are indicative only: its jerk is not the trajectory's at those switches.
"""

from __future__ import annotations

import numpy as np


class SampledPositions:
    """``positions(ts)`` from samples.

    Args:
        times: sample times [s], increasing, shape (m,).
        positions: [rad], shape (m, dof); velocities [rad/s]; accelerations [rad/s^2].
    """

    def __init__(self, times: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                 accelerations: np.ndarray) -> None:
        self.t = np.asarray(times, float)
        if self.t.ndim != 1 or len(self.t) < 2 or np.any(np.diff(self.t) <= 0):
            raise ValueError("times must be increasing, at least two samples")
        self.q = np.asarray(positions, float)
        self.v = np.asarray(velocities, float)
        self.a = np.asarray(accelerations, float)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def __call__(self, ts: np.ndarray) -> np.ndarray:
        """Positions [rad] at ``ts`` [s] from the first sample, shape (len(ts), dof)."""
        t = np.clip(np.atleast_1d(np.asarray(ts, float)) + self.t[0], self.t[0], self.t[-1])
        i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        h = (self.t[i + 1] - self.t[i])[:, None]
        s = ((t - self.t[i])[:, None]) / h
        s2, s3 = s * s, s * s * s
        s4, s5 = s3 * s, s3 * s2
        h0 = 1 - 10 * s3 + 15 * s4 - 6 * s5
        h1 = s - 6 * s3 + 8 * s4 - 3 * s5
        h2 = 0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5
        h3 = 0.5 * s3 - s4 + 0.5 * s5
        h4 = -4 * s3 + 7 * s4 - 3 * s5
        h5 = 10 * s3 - 15 * s4 + 6 * s5
        q, v, a = self.q, self.v, self.a
        return (h0 * q[i] + h1 * h * v[i] + h2 * h * h * a[i]
                + h3 * h * h * a[i + 1] + h4 * h * v[i + 1] + h5 * q[i + 1])
