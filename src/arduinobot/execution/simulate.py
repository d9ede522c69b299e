"""Replay a planned trajectory on the MuJoCo twin (``arduinobot plan --simulate``).

The twin starts at rest at the trajectory's first point, among the request's obstacles,
follows the trajectory at the controller rate (faster than real time) and settles; the
report gives the tracking error, the peak actuator force against the effort limit and
every contact. Needs mujoco (the ``sim`` extra); the plot needs matplotlib.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from arduinobot.description import Description
from arduinobot.execution.executor import ExecuteOptions, Executor
from arduinobot.execution.robots.mjcf import Progress
from arduinobot.execution.segments import SampledTrajectory, check_fits
from arduinobot.planner.cache import ArtifactCache

if TYPE_CHECKING:
    from arduinobot.execution.robots.sim_arduinobot import SimArduinobot


@dataclass(frozen=True, eq=False)
class SimulationReport:
    """The twin's replay of one trajectory.

    Attributes:
        joint_names: column order.
        duration: [s] of the trajectory.
        tracking_error: per joint, max |simulated - commanded| [rad] while it plays.
        final_error: per joint, |simulated - goal| [rad] after settling.
        peak_force, peak_need, effort, saturated_steps, steps, contacts, contact_steps:
            the twin's :class:`~arduinobot.execution.robots.sim_arduinobot.SimStats` of the replay
            (``peak_need`` is its ``peak_feedforward``) [N m].
        times (m,) [s], commanded and simulated positions (m, dof) [rad].
        model: the robot replayed on: its name and the file it was read from.
    """

    joint_names: tuple[str, ...]
    duration: float
    tracking_error: tuple[float, ...]
    final_error: tuple[float, ...]
    peak_force: tuple[float, ...]
    peak_need: tuple[float, ...]
    effort: tuple[float, ...]
    saturated_steps: int
    steps: int
    contacts: tuple[tuple[str, str], ...]
    contact_steps: int
    times: np.ndarray = field(repr=False)
    commanded: np.ndarray = field(repr=False)
    simulated: np.ndarray = field(repr=False)
    model: str = ""

    @property
    def force_ratio(self) -> float:
        """The largest peak actuator force over its limit."""
        return max(f / e for f, e in zip(self.peak_force, self.effort))

    @property
    def need_ratio(self) -> float:
        """The largest torque the trajectory needs over its limit (> 1: more than the
        motors can give)."""
        return max(f / e for f, e in zip(self.peak_need, self.effort))


def simulate(description: Description, trajectory: SampledTrajectory, *,
             obstacles: Sequence[Mapping[str, Any]] = (), rate: float = 100.0,
             settle: float = 0.5, twin: SimArduinobot | None = None,
             cache: ArtifactCache | None = None,
             progress: Progress | None = None, ground: bool = True) -> SimulationReport:
    """Replay ``trajectory`` on a fresh twin (or ``twin``, a :class:`SimArduinobot` to
    reuse: it is reset to the trajectory's start) and measure it; ``cache``,
    ``progress`` and ``ground`` (its floor, as the plan had the ground) go to a fresh
    twin (see :class:`SimArduinobot`).

    Raises:
        TrajectoryMismatch: the trajectory's joints or limits do not fit ``description``.
    """
    from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
    check_fits(trajectory, description)
    names = description.robot.actuated_joints if twin is None else twin.joint_names
    positions = trajectory.for_joints(names, np.zeros(len(names))).positions
    if twin is None:
        twin = SimArduinobot(description, obstacles=obstacles, initial=positions[0],
                             cache=cache, progress=progress, ground=ground)
    else:
        twin.reset(positions[0])
    ex = Executor.for_description(twin, description, options=ExecuteOptions(
        rate=rate, realtime=False, settle=settle, settle_velocity=1e-3))
    rep = ex.execute(trajectory)
    st = twin.stats()
    playing = np.array([p == "trajectory" for p in rep.phases])
    target = np.vstack([rep.q[1:], rep.q[-1:]])  # the state after tick k vs tick k+1's
    err = np.max(np.abs(rep.measured - target)[playing], axis=0)
    return SimulationReport(
        tuple(names), trajectory.duration, tuple(map(float, err)),
        tuple(map(float, np.abs(rep.measured[-1] - positions[-1]))), st.peak_force,
        st.peak_feedforward, st.effort,
        st.saturated_steps, st.steps, st.contacts, st.contact_steps, rep.times, rep.q,
        rep.measured, f"'{description.robot.name}' ({description.robot.source or 'no file'})"
    )


def summary(r: SimulationReport) -> str:
    w = max([10, *(len(n) + 2 for n in r.joint_names)])  # long names keep the columns
    lines = [f"simulation (MuJoCo twin) of {r.model}: {r.duration:.3f} s, {r.steps} physics "
             "steps; contacts: " + (", ".join("/".join(p) for p in r.contacts) or "none"),
             f"{'joint':<{w}}{'track err':>12}{'final err':>12}{'needs':>12}"
             f"{'|force| peak':>14}{'limit':>8}"]
    for i, n in enumerate(r.joint_names):
        lines.append(f"{n:<{w}}{1000 * r.tracking_error[i]:>7.3f} mrad"
                     f"{1000 * r.final_error[i]:>7.3f} mrad{r.peak_need[i]:>8.2f} N m"
                     f"{r.peak_force[i]:>10.2f} N m{r.effort[i]:>8.1f}")
    lines.append(f"the trajectory needs {100 * r.need_ratio:.1f}% of the effort limit; the "
                 f"servos (feedback on top) peak at {100 * r.force_ratio:.1f}%, at the limit "
                 f"in {r.saturated_steps} of {r.steps} steps")
    return "\n".join(lines)


def plot(r: SimulationReport, out: str) -> None:
    """Commanded vs simulated positions, and the tracking error, saved to ``out``."""
    import matplotlib  # cmd_plan checked that it is there
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(9, 7))
    target = np.vstack([r.commanded[1:], r.commanded[-1:]])
    t_meas = r.times + (r.times[1] - r.times[0] if len(r.times) > 1 else 0.0)
    for i, n in enumerate(r.joint_names):
        line, = a1.plot(r.times, r.commanded[:, i], lw=1.5, label=f"{n} commanded")
        a1.plot(t_meas, r.simulated[:, i], ls="--", color=line.get_color(), lw=1,
                label=f"{n} simulated")
        a2.plot(t_meas, 1000 * (r.simulated[:, i] - target[:, i]), color=line.get_color(),
                label=n)
    a1.set_ylabel("position [rad]")
    a1.legend(fontsize="x-small", ncol=2)
    a2.set_ylabel("simulated - commanded [mrad]")
    a2.set_xlabel("time [s]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
    fig.suptitle(f"MuJoCo twin: peak force {100 * r.force_ratio:.0f}% of the effort limit, "
                 f"contacts: {len(r.contacts)}")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
