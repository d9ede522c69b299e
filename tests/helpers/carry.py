"""A carried box swung over a table, for the carried-object tests (planner, twin, service):
:class:`CarryCase`, and :func:`shipped_case` for a module's fixture::

    case = pytest.fixture(shipped_case, scope="module", name="case")
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from arduinobot.description import load_description
from arduinobot.planner.planning.goals import JointGoal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.scene.obstacles import AttachedObject, Obstacle


class CarryCase:
    """A swing of joint 1 over a table: free for the bare arm, but a box hanging below the
    tool would sweep through the table's top on the direct way."""

    def __init__(self, description, tcp) -> None:
        # ``tcp``: between the fingers (the course model has no tcp.yaml: its tool frame
        # is the claw support's origin, above the fingers; its geometry is the shipped one)
        self.d = description
        self.mp = MotionPlanner(description)
        kin = self.mp.context.world(()).kin
        self.link, self.tcp = tcp.parent_link, tcp
        q0 = np.zeros(kin.dof)
        t = kin.link_pose(q0, self.link)
        tool = t[:3, :3] @ np.asarray(tcp.xyz, float) + t[:3, 3]
        scale = float(np.linalg.norm(tool[:2]))  # the arm's reach, whatever its units
        down = t[:3, :3].T @ np.array([0.0, 0.0, -1.0])  # world down in the link's frame
        length = 0.3 * scale
        centre = np.asarray(tcp.xyz, float) + down * (length / 2 + 0.02 * scale)
        # a box hanging below the tool (axes: the link's, its long edge along world z at 0)
        size = np.abs(down) * length + (1 - np.abs(down)) * 0.05 * scale
        self.box = Obstacle("carried_box", "box", size=tuple(size), xyz=tuple(centre))
        # the table's top between the tool and the box's bottom, under the tool at q = 0
        top = tool[2] - 0.02 * scale - 0.5 * length
        thick = 0.05 * scale
        self.table = Obstacle("table", "box", size=(0.5 * scale, 0.35 * scale, thick),
                              xyz=(tool[0], tool[1], top - thick / 2))
        j1 = kin.joint_names[0]
        self.start = {j1: -0.8}
        self.goal = JointGoal({j1: 0.8})
        self.names = list(kin.joint_names)

    def attached(self, mass: float = 0.0) -> AttachedObject:
        return AttachedObject(self.box, self.link, mass=mass)

    def request(self, attached=(), **kw) -> MotionRequest:
        return MotionRequest(goal=self.goal, start=self.start, obstacles=(self.table,),
                             attached=tuple(attached), seed=3, planning_time=5.0, **kw)

    def q(self, state: Mapping[str, float]) -> np.ndarray:
        """The joint vector (ordered as :attr:`names`) of ``state``, the others at 0."""
        return np.array([state.get(n, 0.0) for n in self.names])


def shipped_case() -> CarryCase:
    """The case on the shipped model."""
    d = load_description(env={})
    return CarryCase(d, d.tcp)
