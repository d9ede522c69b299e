"""The page's planning panel: pick a goal (a marked slider pose or a named state), plan
from the shown pose, and hand the trajectory to the playback panel."""

from __future__ import annotations

import logging
import threading

from arduinobot.client.errors import ServiceError
from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.planner.planning.goals import JointGoal, NamedGoal
from arduinobot.viewer.app import RobotViewer
from arduinobot.viewer.planning import Goal, Group, PlanBackend
from arduinobot.viewer.playback import PlaybackPanel

_log = logging.getLogger(__name__)

MARKED = "marked pose"


class PlanningPanel:
    """Adds a "Planning" folder to ``viewer``'s page; plans with ``backend``."""

    def __init__(self, viewer: RobotViewer, playback: PlaybackPanel, backend: PlanBackend) -> None:
        self.viewer = viewer
        self.playback = playback
        self.backend = backend
        self.marked: dict[str, float] | None = None
        self._busy = threading.Lock()
        srdf = viewer.description.srdf
        self._states = {label: (st.name, st.group)
                        for label, st in srdf.labelled_states().items()} if srdf else {}
        groups = ("all", *(srdf.groups if srdf is not None else ()))
        gui = viewer.server.gui
        with gui.add_folder("Planning"):
            gui.add_markdown(f"Plans from the shown pose, {backend.name}.")
            self._mark = gui.add_button("Mark sliders as goal")
            self._mark.on_click(lambda _e: self.mark_goal())
            self._goal = gui.add_dropdown("Goal", (MARKED,) + tuple(self._states),
                                          initial_value=next(iter(self._states), MARKED))
            self._group = gui.add_dropdown("Group (marked pose)", groups, initial_value="all")
            self._plan = gui.add_button("Plan")
            self._plan.on_click(lambda _e: self.plan_async())
            self._status = gui.add_markdown("")
        self.done = threading.Event()

    def mark_goal(self) -> None:
        """Remember the sliders' pose as the goal."""
        q = self.viewer.q
        self.marked = {n: float(v) for n, v in zip(self.viewer.joint_names, q)}
        self._goal.value = MARKED
        self._status.content = "Goal marked: " + ", ".join(
            f"{n}={v:+.2f}" for n, v in self.marked.items())

    def goal(self) -> tuple[Goal, Group]:
        """The chosen goal and the group that moves."""
        name = self._goal.value
        if name != MARKED:
            state, group = self._states[name]
            return NamedGoal(state), group
        if self.marked is None:
            raise InvalidRequest("mark a goal first (move the sliders, press 'Mark sliders "
                                 "as goal', move them back to the start)", field="goal")
        group = self._group.value
        joints = self.viewer.description.srdf.groups[group].joints \
            if group != "all" and self.viewer.description.srdf is not None \
            else self.viewer.joint_names
        return JointGoal({n: v for n, v in self.marked.items() if n in joints}), group

    def plan_async(self) -> None:
        """Plan in a worker thread (the page stays live); ``done`` is set when it ends."""
        if not self._busy.acquire(blocking=False):
            return
        self.done.clear()
        self._plan.disabled = True
        self._status.content = f"Planning ({self.backend.name})…"
        threading.Thread(target=self._plan_worker, name="viewer-plan", daemon=True).start()

    def _plan_worker(self) -> None:
        try:
            goal, group = self.goal()
            start = {n: float(v) for n, v in zip(self.viewer.joint_names, self.viewer.q)}
            traj = self.backend.plan(goal, start=start, group=group)
            self.playback.load(traj, source="planned")
            self._status.content = f"Planned {traj.duration:.2f} s; playing."
            self.playback.toggle()
        except (PlanningError, ServiceError) as e:
            self._status.content = f"**{type(e).__name__}**: {e}"
        except Exception as e:  # the page must say why, whatever failed; logged in full
            _log.exception("planning failed")
            self._status.content = f"**{type(e).__name__}**: {e}"
            raise
        finally:
            self._plan.disabled = False
            self._busy.release()
            self.done.set()
