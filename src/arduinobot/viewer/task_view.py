"""Playing a task in the viewer: the whole task on the scrubber with each step marked,
the carried object moving with the link that holds it, each straight-line move's line.

Reads a task's ``planned`` reply (``<prefix>/task``, or ``arduinobot task --report``'s
``planned``), each step with its plan. The poses are computed here (forward kinematics
of the viewer's model), so :class:`TaskPlayback` is tested without a browser.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.execution.segments import InvalidTrajectory
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.scene.obstacles import Obstacle
from arduinobot.viewer.trajectory import PlaybackTrajectory


@dataclass(frozen=True)
class Carry:
    """``object`` held by ``link`` from ``start`` to ``end`` [s] (None: to the end), at
    ``offset`` in the link's frame, shape (4, 4)."""

    object: str
    link: str
    start: float
    end: float | None
    offset: np.ndarray


@dataclass(frozen=True)
class TaskPlayback:
    """A planned task ready to play.

    Attributes:
        trajectory: the whole task, steps joined (a wait holds still).
        marks: (start time [s], "index kind label") of each step.
        lines: (start, end) [m] of each straight-line move's tcp line.
        obstacles: the scene the task starts in.
        carries: what the robot carries, when.
    """

    name: str
    trajectory: PlaybackTrajectory
    marks: tuple[tuple[float, str], ...]
    lines: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...]
    obstacles: tuple[Obstacle, ...]
    carries: tuple[Carry, ...]

    @classmethod
    def from_reply(cls, body: Mapping[str, Any], kin: Kinematics) -> TaskPlayback:
        """From a ``planned`` reply (or a ``task --report`` holding one).

        Raises:
            InvalidTrajectory: no steps, or a motion step without its plan (planned with
                ``trajectories`` false).
        """
        body = body.get("planned", body)
        steps = body.get("steps")
        if not isinstance(steps, list) or not steps:
            raise InvalidTrajectory("not a planned task: no steps (a <prefix>/task reply "
                                    "or `arduinobot task --report` file)")
        names = tuple(body["joint_names"])
        ts, qs, qds = [np.zeros(1)], [_vec(steps[0]["start"], names)[None]], \
            [np.zeros((1, len(names)))]
        marks, lines = [], []
        for s in steps:
            t0 = float(s["start_time"])
            label = f"{s['index']} {s['kind']}" + (f" {s['label']}" if s.get("label") else "")
            marks.append((t0, label))
            if s["kind"] in ("move", "line", "gripper"):
                if "plan" not in s:
                    raise InvalidTrajectory(f"step {s['index']} has no plan (ask with "
                                            "trajectories true, or task --report)")
                tr = PlaybackTrajectory.from_json(s["plan"])
                idx = [tr.joint_names.index(n) for n in names]
                keep = tr.times > 1e-12
                ts.append(t0 + tr.times[keep])
                qs.append(tr.positions[keep][:, idx])
                vel = tr.velocities if tr.velocities is not None else np.zeros_like(tr.positions)
                qds.append(vel[keep][:, idx])
                line = s["plan"].get("line")
                if line:
                    lines.append((tuple(line["start"]), tuple(line["end"])))
            elif float(s["duration"]) > 0:
                ts.append(np.array([t0 + float(s["duration"])]))
                qs.append(_vec(s["end"], names)[None])
                qds.append(np.zeros((1, len(names))))
        traj = PlaybackTrajectory(names, np.concatenate(ts), np.concatenate(qs),
                                  velocities=np.concatenate(qds))
        obstacles = tuple(Obstacle.from_mapping(o, where=f"obstacles[{i}]")
                          for i, o in enumerate(body.get("obstacles", [])))
        return cls(str(body.get("name") or "task"), traj, tuple(marks), tuple(lines),
                   obstacles, _carries(steps, names, obstacles, kin))

    def object_pose(self, object_id: str, t: float, kin: Kinematics) -> np.ndarray | None:
        """Where ``object_id`` is at time ``t`` [s], shape (4, 4): with the link that
        holds it while carried, where it was let go after; None: not a carried object."""
        carry = next((c for c in self.carries if c.object == object_id), None)
        if carry is None:
            return None
        if t < carry.start:
            return next(o.pose() for o in self.obstacles if o.id == object_id)
        at = t if carry.end is None else min(t, carry.end)
        return kin.link_pose(self.trajectory.at(at), carry.link) @ carry.offset


def _vec(state: Mapping[str, float], names: Sequence[str]) -> np.ndarray:
    return np.array([float(state[n]) for n in names], float)


def _carries(steps: list[dict[str, Any]], names: tuple[str, ...],
             obstacles: tuple[Obstacle, ...], kin: Kinematics) -> tuple[Carry, ...]:
    poses = {o.id: o.pose() for o in obstacles}
    out: list[Carry] = []
    for s in steps:
        t = float(s["start_time"])
        if s["kind"] == "attach" and s.get("object") in poses:
            link_pose = kin.link_pose(_vec(s["end"], names), s["link"])
            out.append(Carry(s["object"], s["link"], t, None,
                             np.linalg.inv(link_pose) @ poses[s["object"]]))
        elif s["kind"] == "detach":
            k = next((i for i, c in enumerate(out) if c.object == s.get("object")
                      and c.end is None), None)
            if k is not None:
                c = out[k]
                out[k] = Carry(c.object, c.link, c.start, t, c.offset)
    return tuple(out)


def show_task(viewer: Any, playback: Any, task: TaskPlayback) -> Callable[[float], None]:
    """Load ``task`` into ``playback`` (a :class:`~.playback.PlaybackPanel` of
    ``viewer``, built with ``task.obstacles``): the scrubber marks the steps, the lines
    are drawn, and each shown time moves the carried objects. Returns that per-time
    callback (also registered on ``playback``)."""
    from arduinobot.viewer.geometry import matrix_to_wxyz

    playback.load(task.trajectory, source=task.name)
    playback.mark(task.marks)
    for i, (a, b) in enumerate(task.lines):
        viewer.server.scene.add_line_segments(
            f"/task/line_{i}", np.array([[a, b]], np.float32),
            colors=(255, 40, 200), thickness=3.0, thickness_units="screen")
    handles = viewer._obstacle_handles

    def move_carried(t: float) -> None:
        for c in task.carries:
            pose = task.object_pose(c.object, t, viewer.kin)
            h = handles.get(c.object)
            if pose is not None and h is not None:
                h.position = tuple(float(v) for v in pose[:3, 3])
                h.wxyz = matrix_to_wxyz(pose[:3, :3])
    playback.on_show.append(move_carried)
    move_carried(0.0)
    return move_carried
