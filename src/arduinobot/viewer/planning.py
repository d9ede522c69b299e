"""Where the viewer's Plan button sends its request: in-process or a running service."""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Protocol

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description import Description
from arduinobot.planner.planning.goals import JointGoal, NamedGoal
from arduinobot.scene.obstacles import Obstacle
from arduinobot.viewer.trajectory import PlaybackTrajectory

if TYPE_CHECKING:  # both are imported on the first plan: the viewer starts without them
    from arduinobot.client.client import PlannerClient
    from arduinobot.planner.planning.pipeline import MotionPlanner
    from arduinobot.viewer.scene_view import ViewerScene

_log = logging.getLogger(__name__)

Group = str  # an SRDF group of the robot, or "all"
SEED = 0  # the planners' seed: the same goal from the same pose plans the same motion
Goal = JointGoal | NamedGoal


class PlanBackend(Protocol):
    """Plans a motion and returns it ready to play."""

    name: str

    def plan(self, goal: Goal, *, start: Mapping[str, float], group: Group) -> PlaybackTrajectory:
        """Raises arduinobot.contract.errors.PlanningError (or a subclass) when no motion is found."""
        ...


class LocalBackend:
    """Plans in this process with :class:`arduinobot.planner.planning.pipeline.MotionPlanner` (built on the
    first request: it takes a few seconds), around ``obstacles`` and the kept scene
    ``scene()`` gives at each plan (the page's: its objects, and what the robot carries)."""

    name = "in-process"

    def __init__(self, description: Description, *, obstacles: Sequence[Obstacle] = (),
                 scene: Callable[[], ViewerScene] | None = None) -> None:
        self.description = description
        self.obstacles = tuple(obstacles)
        self.scene = scene
        self._planner: MotionPlanner | None = None

    def plan(self, goal: Goal, *, start: Mapping[str, float], group: Group) -> PlaybackTrajectory:
        from arduinobot.planner.planning.pipeline import MotionPlanner, MotionRequest

        planner = self._planner
        if planner is None:
            planner = self._planner = MotionPlanner(self.description)
        kept = self.scene() if self.scene is not None else None
        res = planner.solve(MotionRequest(
            goal=goal, start=dict(start), group=group, seed=SEED,
            obstacles=self.obstacles + (kept.obstacles if kept is not None else ()),
            attached=kept.attached if kept is not None else ()))
        _log.info("planned %.2f s of motion with %s in %.3f s", res.trajectory.duration,
                  res.planner, res.timing.get("total", float("nan")))
        return PlaybackTrajectory.from_json(res.trajectory.to_dict())


class RemoteBackend:
    """Plans through a running `arduinobot serve`, with :class:`arduinobot.client.client.PlannerClient`
    (connected on the first request). Its failures raise :class:`arduinobot.client.errors.ServiceError`
    subclasses."""

    def __init__(self, endpoint: str, *, obstacles: Sequence[Obstacle] = (),
                 prefix: str = "arduinobot") -> None:
        """Raises:
            InvalidRequest: an obstacle whose shape means nothing to another process
                (a mesh file's path: :attr:`arduinobot.scene.shapes.Shape.portable`)."""
        for i, o in enumerate(obstacles):
            if not o.geometry.portable:
                raise InvalidRequest(
                    f"'{o.id}' is a {o.shape}: the service takes boxes, spheres and cylinders "
                    "(plan without --connect to plan around it in this process)",
                    field=f"obstacles[{i}].shape")
        self.endpoint, self.prefix = endpoint, prefix
        self.name = f"through the service at {endpoint} (around its kept scene)"
        self.obstacles = tuple(obstacles)
        self._client: PlannerClient | None = None

    def request(self, goal: Goal, *, start: Mapping[str, float], group: Group) -> dict:
        """The v1 plan request (src/arduinobot/contract/schema/plan_request.json)."""
        wire_goal = ({"named": goal.name} if isinstance(goal, NamedGoal)
                     else {"joints": dict(goal.values)})
        return {"goal": wire_goal, "start": dict(start), "group": group,
                "obstacles": [obstacle_json(o) for o in self.obstacles], "seed": SEED}

    def plan(self, goal: Goal, *, start: Mapping[str, float], group: Group) -> PlaybackTrajectory:
        from arduinobot.client.client import PlannerClient

        client = self._client
        if client is None:
            client = self._client = PlannerClient(self.endpoint, prefix=self.prefix)
        res = client.plan(self.request(goal, start=start, group=group))
        return PlaybackTrajectory.from_json(res.raw)


def obstacle_json(o: Obstacle) -> dict:
    """An obstacle in the service's wire format."""
    return o.to_json()
