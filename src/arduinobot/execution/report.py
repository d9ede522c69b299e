"""What an execution did: the per-tick record and the report built from it."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Literal

import numpy as np

from arduinobot.contract.outcomes import Outcome
from arduinobot.execution.robots.base import JointState
from arduinobot.planner.kinematics.limits import JointLimits

Phase = Literal["move_to_start", "trajectory", "stop", "settle"]


@dataclass(frozen=True)
class Tick:
    """One control tick: its index, time [s] since the execution began, the phase, the
    trajectory time [s] and progress (0..1), the setpoint (q [rad], qd [rad/s], qdd
    [rad/s^2]) and the robot's state after the tick."""

    index: int
    time: float
    phase: Phase
    trajectory_time: float
    progress: float
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    state: JointState


@dataclass(frozen=True, eq=False)
class ExecutionReport:
    """What an execution did.

    Attributes:
        outcome: completed, written (played whole on a robot that reports nothing
            back: :mod:`arduinobot.contract.outcomes`), or cancelled (stopped at rest).
        joint_names: the commanded joints (column order of the arrays).
        trajectory_duration: [s] of the trajectory asked for.
        duration: [s] from the first tick to the last.
        ticks: ticks played; late_ticks: how many started over half a period late;
            max_lateness [s].
        cancelled_at: trajectory time [s] of the cancel; stop_time [s] the stop took.
        times (m,) [s]; phases (m,); commanded q/qd/qdd (m, dof); measured positions and
            velocities (m, dof) of the commanded joints.
        peak_ratio: per quantity (velocity, acceleration, jerk), the largest commanded
            value over its limit (from the setpoints' finite differences for jerk).
        max_tracking_error: per joint, max |measured - commanded| [rad], the state read
            at the end of a tick against the setpoint for that moment (the next tick's).
    """

    outcome: Outcome
    joint_names: tuple[str, ...]
    trajectory_duration: float
    duration: float
    ticks: int
    late_ticks: int
    max_lateness: float
    cancelled_at: float | None
    stop_time: float | None
    times: np.ndarray = field(repr=False)
    phases: tuple[Phase, ...] = field(repr=False)
    q: np.ndarray = field(repr=False)
    qd: np.ndarray = field(repr=False)
    qdd: np.ndarray = field(repr=False)
    measured: np.ndarray = field(repr=False)
    measured_velocity: np.ndarray = field(repr=False)
    peak_ratio: dict[str, float] = field(default_factory=dict)
    max_tracking_error: tuple[float, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The summary, JSON-ready: every field but the per-tick arrays (those kept out
        of the repr), and the final measured positions."""
        summary = {f.name: getattr(self, f.name) for f in fields(self) if f.repr}
        return {**summary, "final_positions": [float(v) for v in self.measured[-1]]}


class Recorder:
    """The ticks of one execution, as they happen."""

    def __init__(self) -> None:
        self.rows: list[tuple] = []
        self.late = 0
        self.max_late = 0.0
        self.traj_time = 0.0

    def add(self, t: float, phase: Phase, traj_t: float, q: np.ndarray, qd: np.ndarray,
            qdd: np.ndarray, st: JointState, names: tuple[str, ...], late: float,
            dt: float) -> None:
        idx = [st.names.index(n) for n in names]
        meas, vel = np.array(st.positions)[idx], np.array(st.velocities)[idx]
        self.rows.append((t, phase, q.copy(), qd.copy(), qdd.copy(), meas, vel))
        self.traj_time = traj_t
        if late > 0.5 * dt:
            self.late += 1
        self.max_late = max(self.max_late, late)

    def report(self, outcome: Outcome, names: tuple[str, ...], traj_duration: float,
               cancelled_at: float | None, stop_time: float | None, lim: JointLimits,
               dt: float) -> ExecutionReport:
        times = np.array([r[0] for r in self.rows])
        q, qd, qdd, meas, vel = (np.array([r[i] for r in self.rows]) for i in range(2, 7))
        jerk = np.diff(qdd, axis=0) / dt if len(qdd) > 1 else np.zeros((1, len(names)))
        peak = {"velocity": float(np.max(np.abs(qd) / lim.velocity)),
                "acceleration": float(np.max(np.abs(qdd) / lim.acceleration)),
                "jerk": float(np.max(np.abs(jerk) / lim.jerk))}
        # the state is read at the end of tick k, when the setpoint is tick k+1's
        target = np.vstack([q[1:], q[-1:]])
        err = tuple(float(v) for v in np.max(np.abs(meas - target), axis=0))
        return ExecutionReport(outcome, names, traj_duration,
                               float(times[-1] - times[0]) if len(times) else 0.0,
                               len(times), self.late, self.max_late, cancelled_at, stop_time,
                               times, tuple(r[1] for r in self.rows), q, qd, qdd, meas, vel,
                               peak, err)
