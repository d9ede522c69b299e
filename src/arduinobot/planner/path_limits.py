"""The limits a time parameterisation works to, and joint torque along a curve.

Both parameterisers take the same :class:`ActiveLimits`: the joint limits after the
request's scaling factors and after any derating the verifier asked for. Along a curve
``c(s)`` inverse dynamics is affine in ``sdd`` and ``sd^2`` (toppra's form)::

    tau(s) = m(s) sdd + b(s) sd^2 + g(s)
    m = ID(c, 0, c') - g,   b = ID(c, c', c'') - g,   g = ID(c, 0, 0)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from arduinobot.contract.errors import InvalidRequest


class BatchDynamics(Protocol):
    def torques_batch(self, qs: np.ndarray, qds: np.ndarray, qdds: np.ndarray) -> np.ndarray: ...


class LimitsLike(Protocol):
    """Per-joint limits as :class:`arduinobot.planner.kinematics.limits.JointLimits` has them, shape
    (dof,) each (read-only: a frozen dataclass's fields are)."""

    @property
    def lower(self) -> np.ndarray: ...
    @property
    def upper(self) -> np.ndarray: ...
    @property
    def velocity(self) -> np.ndarray: ...
    @property
    def acceleration(self) -> np.ndarray: ...
    @property
    def jerk(self) -> np.ndarray: ...
    @property
    def effort(self) -> np.ndarray: ...


@dataclass(frozen=True)
class Derating:
    """Factors in (0, 1] applied on top of the request's limits after a failed check."""

    velocity: float = 1.0
    acceleration: float = 1.0
    jerk: float = 1.0
    effort: float = 1.0

    def __post_init__(self) -> None:
        for name in ("velocity", "acceleration", "jerk", "effort"):
            v = getattr(self, name)
            if not (0.0 < v <= 1.0):
                raise InvalidRequest(f"{v!r} must be in (0, 1]", field=f"derating.{name}")

    def to_dict(self) -> dict[str, float]:
        return {"velocity": self.velocity, "acceleration": self.acceleration,
                "jerk": self.jerk, "effort": self.effort}


@dataclass(frozen=True)
class ActiveLimits:
    """Per-joint limits a parameteriser must respect, shape (dof,) each.

    velocity [rad/s], acceleration [rad/s^2], jerk [rad/s^3], effort [N m] (symmetric).
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    effort: np.ndarray

    @classmethod
    def from_limits(cls, limits: LimitsLike, derating: Derating = Derating()) -> ActiveLimits:
        """``limits`` already carry the request's scaling; ``derating`` tightens them further."""
        return cls(np.asarray(limits.velocity, float) * derating.velocity,
                   np.asarray(limits.acceleration, float) * derating.acceleration,
                   np.asarray(limits.jerk, float) * derating.jerk,
                   np.asarray(limits.effort, float) * derating.effort)


def torque_coefficients(dynamics: BatchDynamics, q: np.ndarray, dq: np.ndarray,
                        ddq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m, b, g) of ``tau = m sdd + b sd^2 + g`` at curve points ``q`` with derivatives
    ``dq = c'(s)``, ``ddq = c''(s)``; every array shape (n, dof) [N m per unit]."""
    n = len(q)
    z = np.zeros_like(q)
    out = dynamics.torques_batch(np.vstack([q, q, q]), np.vstack([z, z, dq]),
                                 np.vstack([z, dq, ddq]))
    g = out[:n]
    return out[n:2 * n] - g, out[2 * n:] - g, g
