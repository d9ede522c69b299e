"""src/arduinobot/planner/collision/proof/motion_check.py: a sampled edge checks each of its states once (the
end and the middle first), and its verdict is every state's, on a real world too."""

from __future__ import annotations

import numpy as np

from arduinobot.planner.collision.proof.motion_check import sampled_motion_valid
from arduinobot.scene.obstacles import Obstacle


class _Blocks:
    """States along one joint, free except those within ``blocked`` of it: counts the
    states it is asked about (the logic under test is which states are asked)."""

    def __init__(self, blocked: list[tuple[float, float]]) -> None:
        self.blocked, self.asked = blocked, []

    def _free(self, q: np.ndarray) -> bool:
        return not any(lo <= q[0] <= hi for lo, hi in self.blocked)

    def is_valid(self, q) -> bool:
        self.asked.append(float(np.asarray(q)[0]))
        return self._free(np.asarray(q))

    def first_invalid(self, qs) -> int:
        for i, q in enumerate(np.asarray(qs)):
            self.asked.append(float(q[0]))
            if not self._free(q):
                return i
        return -1


def _count(a: np.ndarray, b: np.ndarray, step: float) -> int:
    # how many states the edge has (as the module counts them)
    return max(1, int(np.ceil(np.max(np.abs(b - a)) / step)))


def test_a_free_edge_asks_about_each_of_its_states_once():
    for m in (1, 2, 3, 4, 5, 10, 11):
        w = _Blocks([])
        a, b = np.zeros(2), np.array([0.0199 * m, 0.0])
        n = _count(a, b, 0.02)
        assert n == m
        assert sampled_motion_valid(w, a, b, 0.02)
        want = sorted(np.round(b[0] * np.arange(1, n + 1) / n, 12))
        assert sorted(np.round(w.asked, 12)) == want, n  # each once, none missed


def test_the_verdict_is_every_states_wherever_a_block_lies():
    rng = np.random.default_rng(3)
    for _ in range(300):
        length = float(rng.uniform(0.001, 0.6))
        lo = float(rng.uniform(0.0, length))
        w = _Blocks([(lo, lo + float(rng.uniform(0.0, 0.03)))])
        a, b = np.zeros(2), np.array([length, 0.0])
        n = _count(a, b, 0.02)
        states = [a + k / n * (b - a) for k in range(1, n + 1)]
        assert sampled_motion_valid(w, a, b, 0.02) == all(w._free(q) for q in states)


def test_on_a_real_world_the_verdict_is_every_states(desc):
    from arduinobot.planner.planning.pipeline import MotionPlanner
    mp = MotionPlanner(desc)
    world = mp.world((Obstacle("wall", "box", size=(0.05, 1.0, 1.0), xyz=(0.0, 0.5, 1.0)),))
    lo, hi = np.array(desc.robot.position_limits(world.kin.joint_names)).T
    rng = np.random.default_rng(5)
    seen = set()
    for _ in range(60):
        a = rng.uniform(lo, hi)
        while not world.is_valid(a):
            a = rng.uniform(lo, hi)
        b = np.clip(a + rng.uniform(-0.6, 0.6, len(a)), lo, hi)
        n = _count(a, b, 0.05)
        every = all(world.is_valid(a + k / n * (b - a)) for k in range(1, n + 1))
        assert sampled_motion_valid(world, a, b, 0.05) == every
        seen.add(every)
    assert seen == {True, False}  # both verdicts met
