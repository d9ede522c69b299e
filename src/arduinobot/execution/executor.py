"""Execute a trajectory on a robot: stream it at the controller rate, stop smoothly.

The :class:`Executor` plays segments tick by tick (100 Hz by default, as the course's
joint_trajectory_controller): at tick ``k`` it samples the segment at ``k / rate``,
commands the robot, lets the tick pass and reads the state back. Ticks are never skipped:
when the loop runs late (a loaded machine), the next setpoints go out at once, so the
sequence of setpoints is always the trajectory's. With ``realtime=False`` (simulation
only) no wall clock paces the ticks.

Cancelling (the ``cancel`` event: Ctrl-C, a cancel request, a lost client) switches at
the next tick to a stop within every limit (:func:`arduinobot.execution.stops.choose_stop`). A new goal
while moving takes over through :meth:`Executor.lookahead` and :meth:`Executor.switch`.
A ``halt`` event stops the same way, for a reason of the caller's (the world changed:
:mod:`arduinobot.service.execute.react`): the report's outcome is then ``stopped``, and
:attr:`Executor.last_stop_end` says where on the trajectory the stop came to rest.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from arduinobot.contract.codes import Code
from arduinobot.contract.outcomes import Outcome
from arduinobot.contract.ranges import RANGES
from arduinobot.description import Description
from arduinobot.execution.report import ExecutionReport, Phase, Recorder, Tick
from arduinobot.execution.robots.base import Robot, RobotError
from arduinobot.execution.ruckig_segments import move_segment
from arduinobot.execution.segments import SampledTrajectory, Segment
from arduinobot.execution.stops import StopKind, TorqueFn, choose_stop, effort_safe
from arduinobot.planner.kinematics.limits import JointLimits

log = logging.getLogger(__name__)


class NotAtStart(RobotError):
    """The robot is farther than the tolerance from the trajectory's start."""

    code: str = Code.NOT_AT_START


class TooLate(RobotError):
    """A blend that cannot happen: the moment it was planned for has passed."""

    code: str = Code.TOO_LATE


class ExecutionBusy(RobotError):
    """The robot is already executing a trajectory."""

    code: str = Code.BUSY


@dataclass(frozen=True)
class ExecuteOptions:
    """How to execute.

    Attributes:
        rate: control rate [Hz].
        start_tolerance: largest allowed |robot - trajectory start| per joint [rad].
        move_to_start: move there first (jerk-limited, a straight line in joint space:
            not collision-checked) instead of refusing (:class:`NotAtStart`).
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
        while (left := t - self.now()) > 0:
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
        if options.rate not in RANGES["sample_rate"]:  # the planner's sample rates
            raise RobotError(f"rate {options.rate!r} must be within {RANGES['sample_rate']}",
                             details={"field": "rate"})
        if robot.realtime_only and not options.realtime:
            raise RobotError("hardware runs in real time only (drop --fast)")
        self.robot, self.limits, self.options, self.on_tick = robot, limits, options, on_tick
        self.torques = torques
        self.last_stop: StopKind | None = None
        #: the trajectory time [s] the last stop came to rest at, when it stayed on the
        #: trajectory's path (a path stop, or its end); None for a joint stop
        self.last_stop_end: float | None = None
        #: wall-clock time [s since the epoch] the last stop's first setpoint went out
        self.stop_sent: float | None = None
        self.blends = 0
        self._switch_lock = threading.Lock()
        # (tick, trajectory, what to do on the executing thread just before it plays)
        self._switch: tuple[int, SampledTrajectory, Callable[[], None] | None] | None = None
        self._playing: tuple[Phase, Segment, int, int] | None = None
        self._tick_index = 0
        self._lock = threading.Lock()

    @classmethod
    def for_description(cls, robot: Robot, description: Description, *,
                        options: ExecuteOptions = ExecuteOptions(),
                        on_tick: Callable[[Tick], None] | None = None) -> Executor:
        """An executor with the description's full limits and inverse dynamics."""
        from arduinobot.planner.kinematics.dynamics import InverseDynamics
        lim = JointLimits.from_description(description, joint_names=robot.joint_names)
        dyn = InverseDynamics(description.robot, robot.joint_names)
        return cls(robot, lim, torques=dyn.torques_batch, options=options, on_tick=on_tick)

    def warm_stops(self) -> None:
        """Choose one stop now (a short move from the robot's state), not first when the
        arm must stop: the first choice in a process loads what the effort check uses
        (measured 1.3 s, then 25-40 ms), and a stop's first setpoint waits for it."""
        names = self.robot.joint_names
        q = self.robot.state().actuated(names)
        goal = np.clip(q + 0.05, self.limits.lower, self.limits.upper)
        lim = self.limits
        seg = move_segment(names, q, goal, velocity=0.1 * lim.velocity,
                           acceleration=0.1 * lim.acceleration, jerk=0.1 * lim.jerk)
        choose_stop(seg, 0.5 * seg.duration, seg.evaluate(0.5 * seg.duration), limits=lim,
                    torques=self.torques)

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

    def switch(self, trajectory: SampledTrajectory, at_tick: int, *,
               on_switch: Callable[[], None] | None = None) -> None:
        """Play ``trajectory`` from tick ``at_tick`` on (it must start in the state
        :meth:`lookahead` gave for that tick). ``on_switch`` runs on the executing thread
        at that tick, before the trajectory's first setpoint (a twin takes the world the
        new trajectory was planned in); its error ends the execution as a driver's does.

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
            self._switch = (at_tick, trajectory.for_joints(names, hold), on_switch)

    def playing(self) -> tuple[Phase, Segment, float] | None:
        """What plays now: the phase, its segment and the segment's time [s] at the
        current tick (None between executions)."""
        with self._switch_lock:
            playing, now = self._playing, self._tick_index
        if playing is None:
            return None
        phase, seg, k0, _ = playing
        return phase, seg, max(0.0, (now - k0) / self.options.rate)

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
                cancel: threading.Event | None = None,
                halt: threading.Event | None = None) -> ExecutionReport:
        """Play ``trajectory`` (after a move to its start if allowed and needed); stop
        smoothly once ``cancel`` (outcome ``cancelled``) or ``halt`` (``stopped``) is set.

        Raises:
            ExecutionBusy: another execution is running on this executor.
            NotAtStart, InvalidTrajectory: before anything moves.
            RobotError: the driver failed mid-way (a port unplugged, a write that stalls):
                its ``details`` add the ``tick``, ``time``, ``phase`` and ``last_commanded``
                (the setpoint the robot last took, by joint [rad]; the arm holds it).
        """
        if not self._lock.acquire(blocking=False):
            raise ExecutionBusy("the robot is already executing a trajectory")
        try:
            return self._execute(trajectory, cancel or threading.Event(),
                                 halt or threading.Event())
        finally:
            self._lock.release()

    def _execute(self, trajectory: SampledTrajectory, cancel: threading.Event,
                 halt: threading.Event) -> ExecutionReport:
        o, lim = self.options, self.limits
        self.last_stop, self.last_stop_end, self.stop_sent = None, None, None
        traj = self.check_start(trajectory)
        names = self.robot.joint_names
        now = self.robot.state().actuated(names)
        plan: list[tuple[Phase, Segment]] = []
        if np.max(np.abs(now - traj.positions[0])) > 1e-9 and o.move_to_start:
            s, goal = o.move_scaling, traj.positions[0]
            plan.append(("move_to_start", effort_safe(lambda f: move_segment(
                names, now, goal, velocity=s * lim.velocity,
                acceleration=f * s * lim.acceleration, jerk=f * s * lim.jerk),
                lim, self.torques)))
            log.info("moving to the start first (%.3f s)", plan[0][1].duration)
        plan.append(("trajectory", traj))
        run = _Playback(self, traj)
        try:
            cancelled_at = run.play(plan, cancel, halt)
            with self._switch_lock:
                self._playing, self._switch = None, None
            stop_time = run.stop(cancelled_at) if cancelled_at is not None else None
            run.settle()
        except RobotError as e:
            # the driver failed mid-motion (a port unplugged, a write that stalls): the
            # arm holds what it was last sent; say what that was, and when
            phase = self._playing[0] if self._playing else None
            with self._switch_lock:
                self._playing, self._switch = None, None
            held = run.sent if run.sent is not None else now  # none taken: where it was
            e.details.update(tick=run.k, time=run.k * run.dt, phase=phase,
                             last_commanded=dict(zip(names, map(float, held))))
            log.error("execution aborted at tick %d (%s): %s", run.k, e.code, e.message)
            raise
        except BaseException:
            # interrupted mid-motion: the robot holds the last setpoint
            log.exception("execution aborted at tick %d", run.k)
            raise
        outcome: Outcome = ("stopped" if halt.is_set() and not cancel.is_set()
                            else "cancelled") if cancelled_at is not None else \
            "completed" if self.robot.feedback else "written"
        return run.rec.report(outcome,
                              names, run.traj.duration, cancelled_at, stop_time, lim, run.dt)


class _Playback:
    """One execution's ticks on ``ex``'s robot: the clock, the record, the setpoint."""

    def __init__(self, ex: Executor, traj: SampledTrajectory) -> None:
        self.ex, self.traj = ex, traj
        self.rec = Recorder()
        self.clock = _Clock(ex.options.realtime)
        self.dt = 1.0 / ex.options.rate
        self.k = 0
        self.cur = traj.evaluate(0.0)
        self.last: tuple[Segment, float] = (traj, 0.0)
        self.sent: np.ndarray | None = None  # the last setpoint the robot took

    def tick(self, phase: Phase, traj_t: float, cur: tuple[np.ndarray, np.ndarray, np.ndarray],
             jerk: np.ndarray) -> None:
        """Command ``cur`` at tick ``k``, let the tick pass, record the state."""
        ex, k, dt = self.ex, self.k, self.dt
        self.clock.wait_until(k * dt)
        late = self.clock.now() - k * dt
        q, qd, qdd = cur
        self.cur = cur
        ex.robot.command(q, qd, qdd, jerks=jerk)
        if phase == "stop" and ex.stop_sent is None:
            ex.stop_sent = time.time()  # the figure: a scene change's arrival to here
        self.sent = q
        ex.robot.advance(dt)
        st = ex.robot.state()
        self.rec.add(k * dt, phase, traj_t, q, qd, qdd, st, ex.robot.joint_names, late, dt)
        if ex.on_tick is not None:
            d = self.traj.duration
            prog = traj_t / d if d > 0 else 1.0
            ex.on_tick(Tick(k, k * dt, phase, traj_t, min(1.0, prog), q, qd, qdd, st))
        self.k += 1

    def _segment(self, seg: Segment, t: float, phase: Phase, traj_t: float) -> None:
        cur = seg.evaluate(t)
        jerk = (seg.evaluate(t + self.dt)[2] - cur[2]) / self.dt
        self.tick(phase, traj_t, cur, jerk)

    def play(self, plan: list[tuple[Phase, Segment]], cancel: threading.Event,
             halt: threading.Event) -> float | None:
        """Play ``plan``'s segments (switching to a blend when one is due); the trajectory
        time of a cancel or halt, or None if it played to the end."""
        ex, rate, dt = self.ex, self.ex.options.rate, self.dt
        self.last = (plan[0][1], 0.0)
        for phase, seg in plan:
            n = int(math.ceil(seg.duration * rate - 1e-9))
            i = 0 if self.k == 0 else 1  # a junction is one tick, not two
            ex._playing = (phase, seg, self.k - i, self.k)
            while i <= n:
                if cancel.is_set() or halt.is_set():
                    break
                with ex._switch_lock:
                    sw, ex._tick_index = ex._switch, self.k
                    if sw is not None and sw[0] == self.k:
                        # blend: the new trajectory starts in this tick's state
                        ex._switch = None
                        seg = self.traj = sw[1]
                        n, i = int(math.ceil(seg.duration * rate - 1e-9)), 0
                        ex._playing = (phase, seg, self.k, self.k)
                        ex.blends += 1
                        log.info("tick %d: blended into a new %.3f s trajectory", self.k,
                                 seg.duration)
                if sw is not None and sw[0] == self.k and sw[2] is not None:
                    sw[2]()  # outside the lock: a twin's new world may take a while
                t = min(i * dt, seg.duration)
                self._segment(seg, t, phase, t if phase == "trajectory" else 0.0)
                self.last = (seg, t)
                i += 1
            if cancel.is_set() or halt.is_set():
                return self.rec.traj_time
        return None

    def stop(self, cancelled_at: float) -> float:
        """Stop within every limit from where the cancel found the arm; the stop's [s]."""
        ex = self.ex
        how, stop = choose_stop(*self.last, self.cur, limits=ex.limits, torques=ex.torques)
        ex.last_stop = how
        # where on the path it rests: a path stop's end, or the segment's own end
        ex.last_stop_end = getattr(stop, "s_end", None) if how == "path" else \
            self.last[0].duration if how == "finish" else None
        log.info("cancelled at %.3f s of the trajectory: stopping (%s) in %.3f s",
                 cancelled_at, how, stop.duration)
        n = int(math.ceil(stop.duration * ex.options.rate - 1e-9))
        for i in range(1, n + 1):
            self._segment(stop, min(i * self.dt, stop.duration), "stop", cancelled_at)
        return stop.duration

    def settle(self) -> None:
        """Hold the last setpoint while the arm still moves (a servo's lag)."""
        o = self.ex.options
        q = self.cur[0]
        held = (q, np.zeros_like(q), np.zeros_like(q))
        for _ in range(int(round(o.settle * o.rate))):
            v = np.abs(self.rec.rows[-1][6]) if self.rec.rows else np.zeros(1)
            if np.all(v < o.settle_velocity):
                break
            self.tick("settle", self.rec.traj_time, held, held[2])
