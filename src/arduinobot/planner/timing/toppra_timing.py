"""Time-optimal timing along the curve with toppra (velocity, acceleration, joint torque).

toppra sees the same blended curve ruckig follows (:mod:`arduinobot.planner.timing.curve`), so its positions
never leave what was collision-checked. Its solution is the path velocity ``sd`` at the
gridpoints; we play it back with constant ``sdd`` between gridpoints (toppra's
``ParametrizeConstAccel`` model) in our own vectorised profile, which keeps every state
exactly on the curve. toppra enforces the constraints only at gridpoints: the verifier
checks every sample afterwards. Constraint objects are slow to build and are cached per
limit set; toppra's None (infeasible) becomes :class:`TrajectoryError`.
"""

from __future__ import annotations

import logging

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint as tc
from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

from arduinobot.contract.errors import TrajectoryError
from arduinobot.planner.path_limits import ActiveLimits, BatchDynamics, torque_coefficients
from arduinobot.planner.timing.curve import Curve, PathCurve
from arduinobot.planner.timing.trajectory import CurveTiming, RestProfile, ScalarProfile

log = logging.getLogger(__name__)

# toppra logs every solve at INFO and warns on each infeasible one; we report failures ourselves.
logging.getLogger("toppra").setLevel(logging.ERROR)


class BatchTorqueConstraint(tc.LinearConstraint):
    """|tau| <= effort via batched inverse dynamics (toppra's own calls ID per gridpoint)."""

    def __init__(self, dynamics: BatchDynamics, effort: np.ndarray) -> None:
        super().__init__()
        self.dynamics = dynamics
        self.effort = np.asarray(effort, float)
        self.dof = len(self.effort)
        self.identical = True
        self.set_discretization_type(tc.DiscretizationType.Interpolation)

    def compute_constraint_params(self, path, gridpoints):  # noqa: ANN001 (toppra's API)
        q, d1, d2 = path(gridpoints), path(gridpoints, 1), path(gridpoints, 2)
        a, b, c = torque_coefficients(self.dynamics, q, d1, d2)
        eye = np.eye(self.dof)
        F = np.vstack([eye, -eye])
        g = np.concatenate([self.effort, self.effort])
        return canlinear_colloc_to_interpolate(a, b, c, F, g, None, None, gridpoints,
                                               identical=True)


class ConstAccelProfile:
    """``s(t)`` with constant ``sdd`` between toppra gridpoints; rest at both ends."""

    def __init__(self, gridpoints: np.ndarray, sd: np.ndarray) -> None:
        s = np.asarray(gridpoints, float)
        sd = np.maximum(np.asarray(sd, float), 0.0)
        ds = np.diff(s)
        vsum = sd[:-1] + sd[1:]
        if np.any(vsum <= 0):
            raise TrajectoryError("toppra returned a standstill inside the path",
                                  details={"stage": "toppra"})
        dt = 2.0 * ds / vsum
        self._s, self._sd = s[:-1], sd[:-1]
        self._u = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
        self._t = np.concatenate(([0.0], np.cumsum(dt)))
        self.duration = float(self._t[-1])
        self._end = float(s[-1])

    def evaluate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ts = np.clip(np.asarray(ts, float), 0.0, self.duration)
        k = np.clip(np.searchsorted(self._t, ts, side="right") - 1, 0, len(self._u) - 1)
        tau = ts - self._t[k]
        u = self._u[k]
        s = self._s[k] + self._sd[k] * tau + 0.5 * u * tau * tau
        sd = self._sd[k] + u * tau
        end = ts >= self.duration
        s[end] = self._end
        sd[end] = 0.0
        return s, sd, np.where(end, 0.0, u)


class TimeOptimalTiming:
    """Time-optimal parameterisation of a :class:`Curve` under the active limits.

    Args:
        dynamics: anything with ``torques_batch``.
        grid_step: max parameter step [rad] between toppra gridpoints.
        min_grid: minimum number of gridpoints per section.
    """

    def __init__(self, dynamics: BatchDynamics, *, grid_step: float = 0.02,
                 min_grid: int = 40) -> None:
        self.dynamics = dynamics
        self.grid_step = grid_step
        self.min_grid = min_grid
        self._constraints: dict[tuple, list] = {}

    def constraints(self, limits: ActiveLimits) -> list:
        """The toppra constraint objects for ``limits``, built once and reused."""
        key = tuple(np.concatenate([limits.velocity, limits.acceleration, limits.effort]))
        found = self._constraints.get(key)
        if found is None:
            v = np.column_stack([-limits.velocity, limits.velocity])
            a = np.column_stack([-limits.acceleration, limits.acceleration])
            found = [tc.JointVelocityConstraint(v),
                     tc.JointAccelerationConstraint(
                         a, discretization_scheme=tc.DiscretizationType.Interpolation),
                     BatchTorqueConstraint(self.dynamics, limits.effort)]
            if len(self._constraints) > 32:
                self._constraints.pop(next(iter(self._constraints)))
            self._constraints[key] = found
        return found

    def gridpoints(self, curve: PathCurve) -> np.ndarray:
        """Uniform in each piece, with every piece boundary a gridpoint, shape (n,)."""
        pts = []
        for s0, L in zip(curve.s0, curve.lengths):
            n = max(2, int(np.ceil(L / self.grid_step)),
                    int(np.ceil(self.min_grid * L / curve.length)))
            pts.append(s0 + np.linspace(0.0, L, n + 1)[:-1])
        pts.append([curve.length])
        return np.concatenate(pts)

    def section(self, curve: PathCurve, limits: ActiveLimits) -> ConstAccelProfile:
        grid = self.gridpoints(curve)
        algo = toppra.algorithm.TOPPRA(self.constraints(limits), curve, gridpoints=grid,
                                       solver_wrapper="seidel")
        algo.compute_parameterization(0.0, 0.0, return_data=True)
        if algo.problem_data.return_code != toppra.algorithm.ParameterizationReturnCode.Ok \
                or algo.problem_data.sd_vec is None:
            raise TrajectoryError(
                "toppra found no feasible time parameterisation of the path",
                details={"stage": "toppra", "return_code": str(algo.problem_data.return_code),
                         "gridpoints": len(grid), "length": curve.length,
                         "velocity": limits.velocity.tolist(),
                         "acceleration": limits.acceleration.tolist(),
                         "effort": limits.effort.tolist()})
        return ConstAccelProfile(grid, algo.problem_data.sd_vec)

    def parameterise(self, curve: Curve, limits: ActiveLimits) -> CurveTiming:
        secs: list[tuple[PathCurve, ScalarProfile]] = [
            (c, self.section(c, limits)) for c in curve.sections if c.length > 1e-12]
        if not secs:
            secs = [(curve.sections[0], RestProfile())]
        return CurveTiming(secs, goal=curve.goal)
