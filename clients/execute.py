"""Execute a trajectory on a robot: stream it at the controller rate, stop smoothly.

The :class:`Executor` plays segments tick by tick (100 Hz by default, as the course's
joint_trajectory_controller): at tick ``k`` it samples the segment at ``k / rate``,
commands the robot, lets the tick pass and reads the state back. Ticks are never skipped:
when the loop runs late (a loaded machine), the next setpoints go out at once, so the
sequence of setpoints is always the trajectory's. With ``realtime=False`` (simulation
only) no wall clock paces the ticks.

- Before moving, the robot must be within ``start_tolerance`` [rad] of the trajectory's
  first point (:class:`NotAtStart` otherwise); ``move_to_start`` first plays a
  jerk-limited ruckig move there (a straight line in joint space, not collision-checked).
- Cancelling (the ``cancel`` event: Ctrl-C, a cancel request, a lost client) switches at
  the next tick to a jerk-limited stop within every limit (:meth:`Executor.choose_stop`):
  preferably braking along the planned path (so the arm stays on the collision-checked
  path), else ruckig's per-joint stop from the commanded state when it stays within the
  position limits, else the rest of the motion (which ends at rest).
- Every tick goes to ``on_tick`` (e.g. the ``<prefix>/joint_states`` publisher).
- A new goal while moving: :meth:`Executor.lookahead` gives a tick a little ahead and
  the setpoint then; a plan from that moving state (``start_velocity`` and
  ``start_acceleration``, see :mod:`planner.moving_start`) handed to
  :meth:`Executor.switch` takes over at that tick, without a jump in position,
  velocity or acceleration.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from description import Description
from planner.limits import JointLimits

from .robots.base import JointState, Robot, RobotError
from .segments import (
    PathStop,
    RestOf,
    RuckigSegment,
    SampledTrajectory,
    Segment,
    move_segment,
    stop_segment,
)

# Inverse dynamics on a batch: (qs, qds, qdds), each (m, dof) -> torques (m, dof) [N m].
TorqueFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]

log = logging.getLogger(__name__)

Phase = Literal["move_to_start", "trajectory", "stop", "settle"]
Outcome = Literal["completed", "cancelled"]
StopKind = Literal["path", "joint", "finish"]


class NotAtStart(RobotError):
    """The robot is farther than the tolerance from the trajectory's start."""

    code = "NOT_AT_START"


class TooLate(RobotError):
    """A blend that cannot happen: the moment it was planned for has passed."""

    code = "TOO_LATE"


class ExecutionBusy(RobotError):
    """The robot is already executing a trajectory."""

    code = "BUSY"


@dataclass(frozen=True)
class ExecuteOptions:
    """How to execute.

    Attributes:
        rate: control rate [Hz].
        start_tolerance: largest allowed |robot - trajectory start| per joint [rad].
        move_to_start: move there first (jerk-limited) instead of refusing.
        move_scaling: velocity, acceleration and jerk scaling of that move, in (0, 1].
        realtime: pace ticks by the wall clock (hardware always is).
        settle: after the last setpoint, hold it for up to this long [s] while any
            joint still moves faster than ``settle_velocity`` [rad/s] (a servo's lag),
            so the last state reported is at rest.
    """

    rate: float = 100.0
    start_tolerance: float = 0.01
    move_to_start: bool = False
    move_scaling: float = 0.5
    realtime: bool = True
    settle: float = 0.5
    settle_velocity: float = 0.01


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
        outcome: completed, or cancelled (then stopped at rest).
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
        """The summary, JSON-ready (no per-tick arrays)."""
        return {"outcome": self.outcome, "joint_names": list(self.joint_names),
                "trajectory_duration": self.trajectory_duration, "duration": self.duration,
                "ticks": self.ticks, "late_ticks": self.late_ticks,
                "max_lateness": self.max_lateness, "cancelled_at": self.cancelled_at,
                "stop_time": self.stop_time, "peak_ratio": dict(self.peak_ratio),
                "max_tracking_error": list(self.max_tracking_error),
                "final_positions": [float(v) for v in self.measured[-1]]}


def plan_start(robot: Robot, description: Description) -> dict[str, float]:
    """The robot's state as a plan request's ``start`` [rad]: measured positions clipped to
    the position limits (a servo resting on a limit reads a hair beyond it)."""
    names = robot.joint_names
    q = robot.state().actuated(names)
    lim = description.robot.position_limits(tuple(names))
    return dict(zip(names, map(float, np.clip(q, lim[:, 0], lim[:, 1]))))


class _Clock:
    """Seconds since ``start``: the wall clock (``realtime``) or a virtual one."""

    def __init__(self, realtime: bool) -> None:
        self.realtime = realtime
        self._t0 = time.monotonic()
        self._virtual = 0.0

    def now(self) -> float:
        return time.monotonic() - self._t0 if self.realtime else self._virtual

    def wait_until(self, t: float) -> None:
        if not self.realtime:
            self._virtual = max(self._virtual, t)
            return
        while True:
            left = t - self.now()
            if left <= 0:
                return
            time.sleep(left)


class Executor:
    """Plays trajectories on one robot (one at a time).

    Args:
        robot: the driver.
        limits: the robot's full (unscaled) limits; its joints must be the robot's.
        torques: inverse dynamics, ``(qs, qds, qdds)`` each (m, dof) -> (m, dof) [N m]:
            with it, stops and moves to the start also keep within the effort limits.
        options: rate, start tolerance, move to start, realtime.
        on_tick: called after every tick (on the executing thread).
    """

    def __init__(self, robot: Robot, limits: JointLimits, *,
                 torques: TorqueFn | None = None,
                 options: ExecuteOptions = ExecuteOptions(),
                 on_tick: Callable[[Tick], None] | None = None) -> None:
        if tuple(limits.joint_names) != tuple(robot.joint_names):
            limits = limits.subset(robot.joint_names)
        if not (math.isfinite(options.rate) and 1.0 <= options.rate <= 1000.0):
            raise RobotError(f"rate {options.rate!r} must be within [1, 1000] Hz")
        if robot.realtime_only and not options.realtime:
            raise RobotError("hardware runs in real time only (drop --fast)")
        self.robot, self.limits, self.options, self.on_tick = robot, limits, options, on_tick
        self.torques = torques
        self.last_stop: StopKind | None = None
        self.blends = 0
        self._switch_lock = threading.Lock()
        self._switch: tuple[int, SampledTrajectory] | None = None
        self._playing: tuple[Phase, Segment, int, int] | None = None
        self._tick_index = 0
        self._lock = threading.Lock()

    @classmethod
    def for_description(cls, robot: Robot, description: Description, *,
                        options: ExecuteOptions = ExecuteOptions(),
                        on_tick: Callable[[Tick], None] | None = None) -> Executor:
        """An executor with the description's full limits and inverse dynamics."""
        from planner.dynamics import InverseDynamics
        lim = JointLimits.from_description(description, joint_names=robot.joint_names)
        dyn = InverseDynamics(description.robot, robot.joint_names)
        return cls(robot, lim, torques=dyn.torques_batch, options=options, on_tick=on_tick)

    # -- blending into a new trajectory while moving ----------------------------------------
    def lookahead(self, lead: float) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """The tick ``lead`` [s] from now and the setpoint (q [rad], qd [rad/s], qdd
        [rad/s^2]) the running trajectory will command then: plan from it (a moving
        start) and hand the result to :meth:`switch` for that tick.

        Raises:
            TooLate: no trajectory is playing, or it ends before then.
        """
        dt = 1.0 / self.options.rate
        with self._switch_lock:
            playing, now = self._playing, self._tick_index
        if playing is None or playing[0] != "trajectory":
            raise TooLate("no trajectory is playing to blend from")
        _, seg, k0, _ = playing
        k = now + max(1, int(math.ceil(lead * self.options.rate)))
        t = (k - k0) * dt
        if t >= seg.duration:
            raise TooLate(f"the motion ends in {seg.duration - (now - k0) * dt:.3f} s, "
                          f"before a blend {lead:g} s ahead: send the goal once it stops")
        q, qd, qdd = seg.evaluate(t)
        return k, q, qd, qdd

    def switch(self, trajectory: SampledTrajectory, at_tick: int) -> None:
        """Play ``trajectory`` from tick ``at_tick`` on (it must start in the state
        :meth:`lookahead` gave for that tick).

        Raises:
            TooLate: that tick has passed, or the motion it blends from has ended.
        """
        names = self.robot.joint_names
        with self._switch_lock:
            if self._playing is None or self._playing[0] != "trajectory":
                raise TooLate("the motion to blend from has ended")
            if at_tick <= self._tick_index:
                raise TooLate(f"tick {at_tick} has passed (now {self._tick_index}): plan "
                              "with a longer lead")
            hold = self._playing[1].evaluate(0.0)[0]
            self._switch = (at_tick, trajectory.for_joints(names, hold))

    def choose_stop(self, seg: Segment, s: float,
                    cur: tuple[np.ndarray, np.ndarray, np.ndarray]
                    ) -> tuple[StopKind, Segment]:
        """How to stop ``seg`` played up to its time ``s`` [s], at commanded ``cur``.

        1. ``path``: brake along the segment's own path (it stays on the collision-checked
           path), the hardest braking tried (path-time deceleration 8, 5.6, 3.9, ...
           [1/s^2]) whose motion keeps every velocity, acceleration, jerk and effort limit
           (checked on 1 ms samples).
        2. ``finish``: when braking on the path needs more path than is left, the rest of
           the segment is the stop (it ends at rest, within every limit).
        3. ``joint``: ruckig's per-joint time-optimal stop (effort-safe), if it stays within
           the position limits.
        4. ``finish`` otherwise.
        """
        lim = self.limits
        dec = 8.0
        for _ in range(10):
            ps = PathStop(seg, s, dec, dec / 0.05)
            if ps.passes_end:
                return "finish", RestOf(seg, s)
            if self.within_limits(ps):
                return "path", ps
            dec *= 0.7
        q, qd, qdd = cur
        js = self.effort_safe(lambda f: stop_segment(
            self.robot.joint_names, q, qd, qdd, velocity=lim.velocity,
            acceleration=np.maximum(f * lim.acceleration, np.abs(qdd)), jerk=f * lim.jerk))
        lo, hi = js.position_extrema()
        if np.all(lo >= lim.lower - 1e-9) and np.all(hi <= lim.upper + 1e-9):
            return "joint", js
        log.warning("no stop within the limits leaves the path early: finishing the motion")
        return "finish", RestOf(seg, s)

    def within_limits(self, seg: Segment, *, step: float = 1e-3) -> bool:
        """Whether ``seg`` keeps positions, velocities, accelerations, jerks (finite
        differences) and, given the inverse dynamics, efforts within the limits on
        ``step`` [s] samples."""
        lim = self.limits
        ts = np.linspace(0.0, seg.duration, max(3, int(math.ceil(seg.duration / step)) + 1))
        q, qd, qdd = (np.array(x) for x in zip(*(seg.evaluate(t) for t in ts)))
        h = ts[1] - ts[0]
        tol = 1 + 1e-6
        ok = bool(np.all(q >= lim.lower - 1e-9) and np.all(q <= lim.upper + 1e-9)
                  and np.all(np.abs(qd) <= lim.velocity * tol)
                  and np.all(np.abs(qdd) <= lim.acceleration * tol)
                  and np.all(np.abs(np.diff(qdd, axis=0)) <= lim.jerk * h * tol))
        if ok and self.torques is not None:
            ok = bool(np.all(np.abs(np.asarray(self.torques(q, qd, qdd)))
                             <= lim.effort * tol))
        return ok

    def effort_safe(self, make: Callable[[float], RuckigSegment]) -> RuckigSegment:
        """``make(scale)`` with the largest scale in (0, 1] (tried as 1, 0.8, 0.64, ...)
        whose motion keeps every joint's torque within 95% of its effort limit (inverse
        dynamics on 1 ms samples). ``scale`` multiplies acceleration and jerk."""
        seg = make(1.0)
        if self.torques is None:
            return seg
        scale = 1.0
        for _ in range(25):
            ts = np.linspace(0.0, seg.duration, max(2, int(seg.duration * 1000) + 1))
            q, qd, qdd = (np.array(x) for x in zip(*(seg.evaluate(t) for t in ts)))
            tau = np.abs(np.asarray(self.torques(q, qd, qdd)))
            ratio = float(np.max(tau / self.limits.effort))
            if ratio <= 0.95:
                return seg
            scale *= 0.8
            seg = make(scale)
        log.warning("no ruckig motion within the effort limits (%.0f%% at scale %.3g)",
                    100 * ratio, scale)
        return seg

    # -- checks -------------------------------------------------------------------------
    def check_start(self, trajectory: SampledTrajectory) -> SampledTrajectory:
        """The trajectory over the robot's joints; raises :class:`NotAtStart` if the robot
        is not where it begins (and ``move_to_start`` is off)."""
        names = self.robot.joint_names
        now = self.robot.state().actuated(names)
        traj = trajectory.for_joints(names, now)
        gap = np.abs(now - traj.positions[0])
        worst = int(np.argmax(gap))
        if gap[worst] > self.options.start_tolerance and not self.options.move_to_start:
            raise NotAtStart(
                f"the robot is not at the trajectory's start: {names[worst]} is at "
                f"{now[worst]:.4f} rad, the trajectory starts at "
                f"{traj.positions[0][worst]:.4f} rad (|diff| {gap[worst]:.4f} > tolerance "
                f"{self.options.start_tolerance:g} rad); plan from the robot's state, or "
                "pass --move-to-start", details={
                    "joint": names[worst], "robot": float(now[worst]),
                    "start": float(traj.positions[0][worst]),
                    "tolerance": self.options.start_tolerance,
                    "robot_positions": dict(zip(names, map(float, now))),
                    "start_positions": dict(zip(names, map(float, traj.positions[0])))})
        return traj

    # -- execution ----------------------------------------------------------------------
    def execute(self, trajectory: SampledTrajectory, *,
                cancel: threading.Event | None = None) -> ExecutionReport:
        """Play ``trajectory`` (after a move to its start if allowed and needed).

        Raises:
            ExecutionBusy: another execution is running on this executor.
            NotAtStart, InvalidTrajectory: before anything moves.
            RobotError: the driver failed mid-way (after a stop was attempted).
        """
        if not self._lock.acquire(blocking=False):
            raise ExecutionBusy("the robot is already executing a trajectory")
        try:
            return self._execute(trajectory, cancel or threading.Event())
        finally:
            self._lock.release()

    def _execute(self, trajectory: SampledTrajectory, cancel: threading.Event
                 ) -> ExecutionReport:
        o, lim = self.options, self.limits
        traj = self.check_start(trajectory)
        names = self.robot.joint_names
        now = self.robot.state().actuated(names)
        plan: list[tuple[Phase, Segment]] = []
        if np.max(np.abs(now - traj.positions[0])) > 1e-9 and o.move_to_start:
            s, goal = o.move_scaling, traj.positions[0]
            plan.append(("move_to_start", self.effort_safe(lambda f: move_segment(
                names, now, goal, velocity=s * lim.velocity,
                acceleration=f * s * lim.acceleration, jerk=f * s * lim.jerk))))
            log.info("moving to the start first (%.3f s)", plan[0][1].duration)
        plan.append(("trajectory", traj))
        rec = _Recorder(len(names))
        clock = _Clock(o.realtime)
        dt = 1.0 / o.rate
        k = 0
        cur = traj.evaluate(0.0)
        cancelled_at: float | None = None
        stop_time: float | None = None
        last: tuple[Segment, float] = (plan[0][1], 0.0)
        try:
            for phase, seg in plan:
                n = int(math.ceil(seg.duration * o.rate - 1e-9))
                first = 0 if k == 0 else 1  # a junction is one tick, not two
                i = first
                self._playing = (phase, seg, k - i, k)
                while i <= n:
                    if cancel.is_set():
                        break
                    with self._switch_lock:
                        sw, self._tick_index = self._switch, k
                        if sw is not None and sw[0] == k:
                            # blend: the new trajectory starts in this tick's state
                            self._switch = None
                            seg = traj = sw[1]
                            n, i = int(math.ceil(seg.duration * o.rate - 1e-9)), 0
                            self._playing = (phase, seg, k, k)
                            self.blends += 1
                            log.info("tick %d: blended into a new %.3f s trajectory", k,
                                     seg.duration)
                    t = min(i * dt, seg.duration)
                    cur = seg.evaluate(t)
                    jerk = (seg.evaluate(t + dt)[2] - cur[2]) / dt
                    prog_t = t if phase == "trajectory" else 0.0
                    self._tick(k, clock, dt, phase, prog_t, traj.duration, cur, jerk, rec)
                    last = (seg, t)
                    k += 1
                    i += 1
                if cancel.is_set():
                    cancelled_at = rec.traj_time
                    break
            with self._switch_lock:
                self._playing, self._switch = None, None
            if cancelled_at is not None:
                how, stop = self.choose_stop(*last, cur)
                stop_time = stop.duration
                self.last_stop = how
                log.info("cancelled at %.3f s of the trajectory: stopping (%s) in %.3f s",
                         cancelled_at, how, stop_time)
                n = int(math.ceil(stop.duration * o.rate - 1e-9))
                for i in range(1, n + 1):
                    t = min(i * dt, stop.duration)
                    cur = stop.evaluate(t)
                    jerk = (stop.evaluate(t + dt)[2] - cur[2]) / dt
                    self._tick(k, clock, dt, "stop", cancelled_at, traj.duration, cur, jerk,
                               rec)
                    k += 1
            held = (cur[0], np.zeros_like(cur[0]), np.zeros_like(cur[0]))
            for _ in range(int(round(o.settle * o.rate))):
                v = np.abs(rec.rows[-1][6]) if rec.rows else np.zeros(1)
                if np.all(v < o.settle_velocity):
                    break
                self._tick(k, clock, dt, "settle", rec.traj_time, traj.duration, held,
                           held[2], rec)
                k += 1
        except BaseException:
            # the driver failed or we are interrupted mid-motion: hold the last setpoint
            log.exception("execution aborted at tick %d", k)
            raise
        return rec.report("cancelled" if cancelled_at is not None else "completed", names,
                          traj.duration, cancelled_at, stop_time, lim, dt)

    def _tick(self, k: int, clock: _Clock, dt: float, phase: Phase, traj_t: float,
              traj_duration: float, cur: tuple[np.ndarray, np.ndarray, np.ndarray],
              jerk: np.ndarray, rec: _Recorder) -> None:
        clock.wait_until(k * dt)
        late = clock.now() - k * dt
        q, qd, qdd = cur
        self.robot.command(q, qd, qdd, jerks=jerk)
        self.robot.advance(dt)
        st = self.robot.state()
        rec.add(k * dt, phase, traj_t, q, qd, qdd, st, self.robot.joint_names, late, dt)
        if self.on_tick is not None:
            prog = traj_t / traj_duration if traj_duration > 0 else 1.0
            self.on_tick(Tick(k, k * dt, phase, traj_t, min(1.0, prog), q, qd, qdd, st))


class _Recorder:
    def __init__(self, dof: int) -> None:
        self.rows: list[tuple] = []
        self.late = 0
        self.max_late = 0.0
        self.traj_time = 0.0

    def add(self, t: float, phase: Phase, traj_t: float, q: np.ndarray, qd: np.ndarray,
            qdd: np.ndarray, st: JointState, names: tuple[str, ...], late: float,
            dt: float) -> None:
        idx = {n: i for i, n in enumerate(st.names)}
        meas = np.array([st.positions[idx[n]] for n in names])
        vel = np.array([st.velocities[idx[n]] for n in names])
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
