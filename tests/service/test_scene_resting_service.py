"""A box resting on a table in the kept scene, attached there, through a real `arduinobot
serve` (issue 42 item 2): a straight line up is planned (certified, verified; an
independent FCL check finds the box never more than ``DEPTH`` into the table and clear at
the end), then a move from the lifted state; a move straight from the resting start is
refused START_IN_COLLISION with the hint, a line along the table (still on it at its end)
GOAL_IN_COLLISION naming the pair, and a check there names the resting pair."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.description.model import rpy_of
from arduinobot.planner.planning.resting import DEPTH, TOUCHING
from tests.helpers.carry import shipped_case
from tests.helpers.serve import start_servers
from tests.planner.planning.test_carried import _box_hits
from tests.planner.planning.test_resting import _box_at, _depth_hits, _gap, _table_under

pytestmark = pytest.mark.slow  # starts a serve process

case = pytest.fixture(shipped_case, scope="module", name="case")


def test_a_resting_box_attached_in_the_kept_scene_is_lifted_by_a_line(case):
    table = _table_under(case)
    t = _box_at(case, np.zeros(len(case.names)))
    box = {"id": case.box.id, "shape": "box", "size": list(case.box.size),
           "xyz": t[:3, 3].tolist(), "rpy": list(rpy_of(t[:3, :3]))}
    srv = start_servers([["--workers", "1"]])[0]
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            c.request("scene/apply", {"add": [table.to_json(), box]})
            got = c.request("scene/apply", {"attach": [{"object": case.box.id,
                                                        "link": case.link}],
                                            "state": {}})
            assert got["attached"] == 1

            # from where it rests, any goal but a line is refused with the hint
            with pytest.raises(errors.StartInCollision) as e:
                c.plan({"start": {}, "goal": {"joints": {case.names[0]: 0.5}}, "seed": 3})
            assert e.value.details["resting"] == [["carried_box", "table"]]
            assert "lift it first with a straight line" in e.value.details["hint"]
            assert '{"line": {"offset": [0, 0, 0.05]}}' in e.value.message
            chk = c.request("check", {"joints": {}})
            assert not chk["valid"] and chk["resting"] == [["carried_box", "table"]]

            # a line along the table ends still on it: refused naming the pair
            with pytest.raises(errors.GoalInCollision) as e:
                c.plan({"start": {}, "goal": {"line": {"offset": [0.02, 0, 0]}}, "seed": 3})
            assert e.value.details["pairs"] == [["carried_box", "table"]]
            assert "still on 'table'" in e.value.message

            # a line up: certified, verified, never more than DEPTH in, clear at its end
            up = c.plan({"start": {}, "goal": {"line": {"offset": [0, 0, 0.03]}},
                         "seed": 3, "trajectory_format": "points"})
            v = up.raw["verification"]
            assert v["ok"] and v["certified"] and v["collision_free"]
            assert up.raw["lifted_off"] == [["carried_box", "table"]]
            qs = np.array([p["positions"] for p in up.raw["trajectory"]["points"]])
            assert _depth_hits(case, qs, table, DEPTH) == 0
            assert _gap(case, qs[-1], table) > TOUCHING

            # from the lifted state a move plans as any other: the box checked again
            lifted = dict(zip(case.names, map(float, qs[-1])))
            move = c.plan({"start": lifted, "goal": {"joints": {case.names[0]: 0.5}},
                           "seed": 3, "planning_time": 5.0,
                           "trajectory_format": "points"})
            assert move.raw["verification"]["ok"] and move.raw["verification"]["certified"]
            assert "lifted_off" not in move.raw
            mq = np.array([p["positions"] for p in move.raw["trajectory"]["points"]])
            assert np.isclose(mq[-1][0], 0.5, atol=1e-3)
            assert _box_hits(case.d, case.names, mq, case.box, case.link, table) == 0
    finally:
        srv.stop()
