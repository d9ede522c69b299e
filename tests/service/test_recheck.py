"""A running motion's rest certified again in a worker (service/plan/recheck.py): the
planner's proof on the tick setpoints; where it is refused, the longest certified prefix."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.service.plan.handlers import Handlers
from tests.helpers.fk import link_pose

NAMES = ["joint_1", "joint_2", "joint_3", "joint_4"]


@pytest.fixture(scope="module")
def handlers(desc):
    return Handlers(desc)


def _sweep(n: int = 200) -> np.ndarray:
    """A joint-space line from home towards joint_1 -1.0 (states one tick apart)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    return s * np.array([-1.0, 0.3, 0.5, 0.0])


def test_a_free_rest_is_certified_and_one_through_an_obstacle_is_not(handlers, desc):
    qs = _sweep()
    free = handlers.handle("recheck", {"joint_names": NAMES, "positions": qs.tolist()})
    assert free["certified"] is True and free["states"] == len(qs)
    assert "safe" not in free
    # a sphere where the claw is at 60% of the sweep
    at = link_pose(desc.robot, "claw_support", NAMES, qs[120])[:3, 3]
    ob = {"id": "intruder", "shape": "sphere", "radius": 0.08, "xyz": at.tolist()}
    got = handlers.handle("recheck", {"joint_names": NAMES, "positions": qs.tolist(),
                                      "obstacles": [ob]})
    assert got["certified"] is False
    k = got["refused"]["state"]
    assert "intruder" in got["refused"]["pair"]
    assert 0 < k < 120  # refused before the claw reaches its centre
    assert 0 <= got["safe"] <= k
    # the prefix through "safe" is certified on its own; one more piece past k is not
    pre = handlers.handle("recheck", {"joint_names": NAMES,
                                      "positions": qs[:got["safe"] + 1].tolist(),
                                      "obstacles": [ob]})
    assert pre["certified"] is True
    more = handlers.handle("recheck", {"joint_names": NAMES,
                                       "positions": qs[:k + 2].tolist(), "obstacles": [ob]})
    assert more["certified"] is False


def test_positions_of_the_wrong_shape_are_refused_naming_the_field(handlers):
    with pytest.raises(InvalidRequest) as e:
        handlers.handle("recheck", {"joint_names": NAMES, "positions": [[0.0, 0.0]]})
    assert e.value.details["field"] == "positions"
