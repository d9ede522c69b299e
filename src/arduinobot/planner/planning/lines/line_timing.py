"""Timing a straight-line move: one jerk-limited profile of the joint curve's parameter,
and the tcp's motion it gives, measured against the Cartesian limits.

The joint curve of a line (its vertices, corners blended, :mod:`arduinobot.planner.timing.curve`)
is followed by a rest-to-rest ruckig profile of its parameter ``s`` per section, with
bounds ``V`` [rad/s], ``A``, ``J`` on ``sd``, ``sdd``, ``sddd`` (:func:`section_profile`).
The tcp's speed, acceleration and angular speed on a fine time grid
(:func:`tcp_motion`) and the joints' (the verifier) decide whether they pass; the
strategy tightens the bounds by the ratio a limit was passed by until both do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from arduinobot.contract.errors import TrajectoryError
from arduinobot.description.moveit_config import CartesianLimits
from arduinobot.description.tcp import Tcp
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.planner.kinematics.ik_numeric import Chain
from arduinobot.planner.kinematics.ik_pose import tool_jacobian
from arduinobot.planner.timing.curve import Curve
from arduinobot.planner.timing.ruckig_timing import RuckigProfile
from arduinobot.planner.timing.trajectory import CurveTiming, RestProfile, ScalarProfile

__all__ = ["Bounds", "section_profile", "line_timing", "TcpMotion", "tcp_motion"]


@dataclass(frozen=True)
class Bounds:
    """Bounds on the curve parameter's speed [rad/s], acceleration and jerk."""

    velocity: float
    acceleration: float
    jerk: float

    def scaled(self, velocity: float = 1.0, acceleration: float = 1.0, jerk: float = 1.0
               ) -> Bounds:
        return Bounds(self.velocity * velocity, self.acceleration * acceleration,
                      self.jerk * jerk)


def section_profile(length: float, bounds: Bounds) -> ScalarProfile:
    """A rest-to-rest, jerk-limited profile of ``s`` over ``length`` [rad] (offline ruckig,
    no intermediate waypoints)."""
    if length <= 0.0:
        return RestProfile()
    inp = InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [0.0], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [length], [0.0], [0.0]
    inp.max_velocity = [bounds.velocity]
    inp.max_acceleration = [bounds.acceleration]
    inp.max_jerk = [bounds.jerk]
    tr = Trajectory(1)
    res = Ruckig(1).calculate(inp, tr)
    if res not in (Result.Working, Result.Finished):
        raise TrajectoryError(f"ruckig could not time the line ({res})",
                              details={"stage": "ruckig"})
    return RuckigProfile([(0.0, tr)])


def line_timing(curve: Curve, bounds: Bounds) -> CurveTiming:
    """Every section of ``curve`` with its own rest-to-rest profile under ``bounds``."""
    return CurveTiming([(sec, section_profile(sec.length, bounds)) for sec in curve.sections],
                       goal=curve.goal)


@dataclass(frozen=True)
class TcpMotion:
    """The tcp on a time grid: ``times`` (m,) [s], ``positions`` (m, 3) [m],
    ``velocities`` (m, 3) [m/s], ``accelerations`` (m, 3) [m/s^2] (central differences
    of the exact velocities), ``angular`` (m, 3) [rad/s], ``rotations`` (m, 3, 3)."""

    times: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    angular: np.ndarray

    def ratios(self, limits: CartesianLimits, velocity_scaling: float,
               acceleration_scaling: float) -> dict[str, float]:
        """The worst ratio to each scaled limit: ``tcp_velocity``, ``tcp_acceleration``
        (speeding up, ``a . v >= 0``: against max_trans_acc; slowing down: against
        |max_trans_dec|), ``tcp_rotation`` (angular speed)."""
        speed = np.linalg.norm(self.velocities, axis=1)
        acc = np.linalg.norm(self.accelerations, axis=1)
        up = np.einsum("ij,ij->i", self.accelerations, self.velocities) >= 0
        a_lim = np.where(up, limits.max_trans_acc, -limits.max_trans_dec) * acceleration_scaling
        return {
            "tcp_velocity": float(speed.max() / (limits.max_trans_vel * velocity_scaling)),
            "tcp_acceleration": float(np.max(acc / a_lim)),
            "tcp_rotation": float(np.linalg.norm(self.angular, axis=1).max()
                                  / (limits.max_rot_vel * velocity_scaling)),
        }


def tcp_motion(kin: Kinematics, chain: Chain, tcp: Tcp, timing: CurveTiming, *,
               step: float = 1e-3) -> TcpMotion:
    """The tcp's motion under ``timing`` on a grid ``step`` [s] apart (and the end)."""
    n = max(3, int(math.ceil(timing.duration / step)) + 1)
    ts = np.linspace(0.0, timing.duration, n)
    q, qd, _ = timing.evaluate(ts)
    p, rot, jp, jw = tool_jacobian(kin, tcp, chain, q)
    qdc = qd[:, chain.columns]
    v = np.einsum("mij,mj->mi", jp, qdc)
    w = np.einsum("mij,mj->mi", jw, qdc)
    a = np.gradient(v, ts, axis=0) if timing.duration > 0 else np.zeros_like(v)
    return TcpMotion(ts, p, rot, v, a, w)
