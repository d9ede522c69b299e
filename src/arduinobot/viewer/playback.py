"""The page's playback panel: load a trajectory, scrub and play it, plot it.

A daemon thread advances the time while playing; every shown time goes through the
scrubber's callback, so the scrubber, the pose and the collision colours always agree.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from arduinobot.viewer import require
from arduinobot.viewer.app import RobotViewer
from arduinobot.viewer.plots import PlotPanel, joint_limits, plot_panels, plot_png
from arduinobot.viewer.trajectory import PlaybackTrajectory, TrajectoryFileError

if TYPE_CHECKING:
    import viser  # the view extra: imported at run time through require()

_SPEEDS = ("0.1", "0.25", "0.5", "1", "2")
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf")
_TICK = 1.0 / 30.0  # [s] between shown frames while playing


class PlaybackPanel:
    """Adds "Playback" and "Plots" folders to ``viewer``'s page."""

    def __init__(self, viewer: RobotViewer) -> None:
        self.viewer = viewer
        self.trajectory: PlaybackTrajectory | None = None
        self.playing = False
        #: called with every shown time [s] after the robot moved (a task's carried objects)
        self.on_show: list[Callable[[float], None]] = []
        self._stop = threading.Event()
        gui = viewer.server.gui
        self._folder = gui.add_folder("Playback")
        with self._folder:
            self._info = gui.add_markdown("No trajectory loaded.")
            self._upload = gui.add_upload_button(
                "Load trajectory JSON", mime_type="application/json",
                hint="a file written by `arduinobot plan --json`")
            self._upload.on_upload(self._uploaded)
            self._scrub = self._scrubber(1.0, disabled=True)
            self._play = gui.add_button("Play", disabled=True)
            self._play.on_click(lambda _e: self.toggle())
            self._speed = gui.add_dropdown("Speed", _SPEEDS, initial_value="1")
            self._loop = gui.add_checkbox("Loop", False)
        self._plot_folder = gui.add_folder("Plots", expand_by_default=False)
        with self._plot_folder:
            self._plots: list[viser.GuiUplotHandle] = []
            self._png = gui.add_button("Download plots as PNG", disabled=True)
            self._png.on_click(self._download_png)
        self._thread = threading.Thread(target=self._run, name="viewer-playback", daemon=True)
        self._thread.start()

    # -- loading -----------------------------------------------------------------------
    def _uploaded(self, _event: object) -> None:
        f = self._upload.value
        try:
            self.load(PlaybackTrajectory.from_json(json.loads(f.content.decode("utf-8"))),
                      source=f.name)
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            self._info.content = f"**Cannot load {f.name}**: not a JSON file: {e}"
        except TrajectoryFileError as e:
            self._info.content = f"**Cannot load {f.name}**: {e}"

    def load(self, traj: PlaybackTrajectory, *, source: str = "") -> None:
        """Show ``traj`` at time 0, ready to play, and plot it.

        Raises:
            TrajectoryFileError: a joint of the trajectory is not an actuated joint.
        """
        unknown = [n for n in traj.joint_names if n not in self.viewer.joint_names]
        if unknown:
            raise TrajectoryFileError(f"joint(s) {', '.join(unknown)} are not actuated joints "
                                      f"of '{self.viewer.description.robot.name}'")
        self.playing = False
        self.trajectory = traj
        self._info.content = (f"{source + ': ' if source else ''}{len(traj.times)} points, "
                              f"{traj.duration:.2f} s, joints {', '.join(traj.joint_names)}")
        self._scrub.max = max(traj.duration, 0.01)
        self._scrub.disabled = False
        self._play.disabled = False
        self._play.label = "Play"
        self._png.disabled = False
        if self._scrub.value != 0.0:
            self._scrub.value = 0.0
        else:
            self._show(0.0)
        self._draw_plots()

    # -- playing -----------------------------------------------------------------------
    def toggle(self) -> None:
        """Play from the scrubber's time (from 0 at the end), or pause."""
        if self.trajectory is None:
            return
        if not self.playing and self._scrub.value >= self.trajectory.duration - 1e-9:
            self._scrub.value = 0.0
        self.playing = not self.playing
        self._play.label = "Pause" if self.playing else "Play"

    def _show(self, t: float) -> None:
        traj = self.trajectory
        if traj is None:
            return
        self.viewer.set_joints(dict(zip(traj.joint_names, traj.at(t))))
        for fn in self.on_show:
            fn(t)

    def _scrubber(self, top: float, *, disabled: bool = False,
                  marks: tuple[tuple[float, str], ...] | None = None,
                  order: float | None = None) -> Any:
        # Any, as add_slider's own return is to mypy (its decorator): viser's handle types
        # its value read-only, though assigning it is how a slider moves
        h = self.viewer.server.gui.add_slider("time [s]", min=0.0, max=top, step=0.01,
                                              initial_value=0.0, disabled=disabled,
                                              marks=marks, order=order)
        h.on_update(lambda _e: self._show(float(h.value)))
        return h

    def mark(self, marks: Sequence[tuple[float, str]]) -> None:
        """Mark times on the scrubber (a task's steps, by index), their labels listed.
        viser sets a slider's marks when it is made: the scrubber is made again, in
        place."""
        old = self._scrub
        with self._folder:
            self._scrub = self._scrubber(
                float(old.max), disabled=old.disabled, order=old.order,
                marks=tuple((float(t), label.split(" ", 1)[0]) for t, label in marks))
        old.remove()
        self._info.content += "\n\n" + "\n".join(f"- {t:.2f} s: {label}"
                                                  for t, label in marks)

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(_TICK):
            now = time.monotonic()
            dt, last = now - last, now
            traj = self.trajectory
            if not self.playing or traj is None:
                continue
            t = float(self._scrub.value) + dt * float(self._speed.value)
            if t >= traj.duration:
                if self._loop.value:
                    t = 0.0
                else:
                    t = traj.duration
                    self.playing = False
                    self._play.label = "Play"
            self._scrub.value = min(t, traj.duration)

    def close(self) -> None:
        self._stop.set()

    # -- plots ---------------------------------------------------------------------------
    def panels(self) -> list[PlotPanel]:
        traj = self.trajectory
        if traj is None:
            return []
        return plot_panels(traj, joint_limits(self.viewer.description, traj.joint_names))

    def png(self) -> bytes:
        """The current trajectory's plots as PNG (needs matplotlib)."""
        return plot_png(self.panels(), title=self.viewer.description.robot.name)

    def _draw_plots(self) -> None:
        uplot = require("viser.uplot")
        gui = self.viewer.server.gui
        for h in self._plots:
            h.remove()
        self._plots = []
        for p in self.panels():
            data = [p.times]
            series = [uplot.Series(label="t [s]")]
            for i, name in enumerate(p.joint_names):
                c = _COLORS[i % len(_COLORS)]
                data.append(p.values[:, i])
                series.append(uplot.Series(label=name, stroke=c, width=1.5))
                for side, lim in (("min", p.lower[i]), ("max", p.upper[i])):
                    if np.isfinite(lim):
                        data.append(np.full_like(p.times, lim))
                        series.append(uplot.Series(label=f"{name} {side}", stroke=c, width=1,
                                                   dash=[4, 4]))
            with self._plot_folder:
                self._plots.append(gui.add_uplot(
                    tuple(np.asarray(d, dtype=np.float64) for d in data), tuple(series),
                    title=f"{p.quantity} [{p.unit}]", aspect=1.6))

    def _download_png(self, event: object) -> None:
        # to the browser that clicked (else to every connected one)
        target = getattr(event, "client", None) or self.viewer.server
        target.send_file_download("trajectory_plots.png", self.png())
