"""Plots of a trajectory: positions, velocities, accelerations and efforts with limits.

:func:`plot_panels` gives the numbers (used by the page's live plots); :func:`plot_png`
draws them with matplotlib (an optional dependency, imported here only).
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from arduinobot.description import Description
from arduinobot.planner.kinematics.applied_limits import KINDS, AppliedLimits, applied_limits
from arduinobot.viewer import require
from arduinobot.viewer.trajectory import PlaybackTrajectory

Quantity = Literal["position", "velocity", "acceleration", "effort"]


@dataclass(frozen=True)
class PlotPanel:
    """One quantity of every joint over time.

    Attributes:
        quantity: what is plotted.
        unit: its unit, e.g. "rad/s".
        times: [s], shape (n,).
        values: shape (n, j), one column per joint (``joint_names``).
        lower: lower limit per joint, shape (j,) (nan: none).
        upper: upper limit per joint, shape (j,) (nan: none).
        limit_note: where the limits came from and their scaling (``joint_limits.yaml
            x0.1``), drawn on the panel; empty if unknown.
    """

    quantity: Quantity
    unit: str
    joint_names: tuple[str, ...]
    times: np.ndarray
    values: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    limit_note: str = ""


def joint_limits(description: Description, joints: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Position lower/upper, velocity, acceleration, jerk and effort limits of ``joints``,
    each shape (j,), as applied at the description's default scaling
    (:func:`applied_limits`)."""
    return limits_of(applied_limits(description, joints))


def limits_of(applied: AppliedLimits) -> dict[str, np.ndarray]:
    """The applied figures of :func:`plot_panels`'s ``limits``."""
    return {k: applied.applied(k) for k in KINDS}


def limit_notes(applied: AppliedLimits) -> dict[str, str]:
    """Per plotted quantity, where its dashed limits came from and their scaling."""
    return {q: applied.origin(q) for q in ("position", "velocity", "acceleration", "effort")}


def plot_panels(traj: PlaybackTrajectory, limits: Mapping[str, np.ndarray], *,
                notes: Mapping[str, str] | None = None) -> list[PlotPanel]:
    """The panels the trajectory has data for (positions always); ``notes`` (quantity ->
    where its limits came from, :func:`limit_notes`) are drawn on them."""
    notes = notes or {}
    specs: list[tuple[Quantity, str, np.ndarray | None, np.ndarray, np.ndarray]] = [
        ("position", "rad", traj.positions, limits["lower"], limits["upper"]),
        ("velocity", "rad/s", traj.velocities, -limits["velocity"], limits["velocity"]),
        ("acceleration", "rad/s²", traj.accelerations, -limits["acceleration"],
         limits["acceleration"]),
        ("effort", "N·m", traj.effort, -limits["effort"], limits["effort"]),
    ]
    return [PlotPanel(q, u, traj.joint_names, traj.times, v, lo, hi, notes.get(q, ""))
            for q, u, v, lo, hi in specs if v is not None]


def plot_figure(panels: list[PlotPanel], *, title: str = "", dpi: int = 110) -> Any:
    """The panels as one matplotlib figure: one row per quantity, limits dashed in each
    joint's colour."""
    matplotlib = require("matplotlib")
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure  # the OO API: no global pyplot state

    fig = Figure(figsize=(9, 2.4 * max(len(panels), 1)), dpi=dpi, layout="constrained")
    axes = fig.subplots(max(len(panels), 1), 1, sharex=True, squeeze=False)[:, 0]
    colors = [f"C{i}" for i in range(10)]
    for ax, p in zip(axes, panels):
        for i, name in enumerate(p.joint_names):
            c = colors[i % len(colors)]
            ax.plot(p.times, p.values[:, i], color=c, label=name, lw=1.6)
            for lim in (p.lower[i], p.upper[i]):
                if np.isfinite(lim):
                    ax.axhline(lim, color=c, lw=0.8, ls="--", alpha=0.6)
        ax.set_ylabel(f"{p.quantity} [{p.unit}]")
        ax.grid(alpha=0.3)
        if p.limit_note:
            ax.text(0.005, 0.98, f"limits: {p.limit_note}", transform=ax.transAxes,
                    va="top", ha="left", fontsize="small", alpha=0.8)
    axes[0].legend(loc="upper right", fontsize="small", ncols=max(1, len(panels[0].joint_names))
                   if panels else 1)
    axes[-1].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    return fig


def plot_png(panels: list[PlotPanel], *, title: str = "", dpi: int = 110) -> bytes:
    """:func:`plot_figure` as PNG."""
    buf = io.BytesIO()
    plot_figure(panels, title=title, dpi=dpi).savefig(buf, format="png")
    return buf.getvalue()
