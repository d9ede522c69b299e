"""A carried object that starts resting on a table (issue 42 item 2, outside a task): a
straight line lifts it off, proven never to press into the table (an independent FCL
check of the box, posed by an independent FK, against the table shrunk by
``resting.DEPTH``, every 0.002 rad of the trajectory) and ending clear of it; a move from
the lifted state plans as any other; a move straight from the resting start is refused
with the hint, a line along the table (still touching at its end) names the pair, a line
down runs into the table's core, and a box stuck deeper than ``TOUCHING`` is no resting
one. On the shipped arm."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from arduinobot.contract.errors import GoalInCollision, LineInterrupted, StartInCollision
from arduinobot.planner.planning.goals import JointGoal, LineGoal
from arduinobot.planner.planning.motion import MotionRequest
from arduinobot.planner.planning.resting import DEPTH, TOUCHING
from arduinobot.scene.obstacles import AttachedObject, Obstacle
from tests.helpers.carry import CarryCase, shipped_case
from tests.helpers.fk import link_pose
from tests.planner.planning.test_carried import _box_hits, _dense

THICK = 0.02  # [m] the table


@pytest.fixture(scope="module")
def case() -> CarryCase:
    return shipped_case()


def _box_at(case: CarryCase, q: np.ndarray) -> np.ndarray:
    """The carried box's world pose (4, 4) at ``q``, by the independent FK."""
    return link_pose(case.d.robot, case.link, case.names, q) @ case.box.pose()


def _table_under(case: CarryCase, sink: float = 0.0) -> Obstacle:
    """A table whose top is at the box's bottom at q = 0 (``sink`` [m] above it: the
    box that far into it)."""
    t = _box_at(case, np.zeros(len(case.names)))
    half = np.asarray(case.box.size) / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                        for sz in (-1, 1)]) * half
    pts = corners @ t[:3, :3].T + t[:3, 3]
    top = float(pts[:, 2].min()) + sink
    centre = pts[:, :2].mean(0)
    return Obstacle("table", "box", size=(0.5, 0.5, THICK),
                    xyz=(float(centre[0]), float(centre[1]), top - THICK / 2))


def _fcl_box(size, t: np.ndarray) -> fcl.CollisionObject:
    return fcl.CollisionObject(fcl.Box(*size), fcl.Transform(t[:3, :3], t[:3, 3]))


def _depth_hits(case: CarryCase, positions: np.ndarray, table: Obstacle, depth: float
                ) -> int:
    # the box against the table shrunk by ``depth`` on every side, state by state
    core = _fcl_box(np.asarray(table.size) - 2 * depth, table.pose())
    hits = 0
    for q in _dense(positions):
        hits += fcl.collide(_fcl_box(case.box.size, _box_at(case, q)), core,
                            fcl.CollisionRequest(), fcl.CollisionResult()) > 0
    return hits


def _gap(case: CarryCase, q: np.ndarray, table: Obstacle) -> float:
    return float(fcl.distance(_fcl_box(case.box.size, _box_at(case, q)),
                              _fcl_box(table.size, table.pose()),
                              fcl.DistanceRequest(), fcl.DistanceResult()))


def _request(case: CarryCase, goal, table: Obstacle, start=None) -> MotionRequest:
    return MotionRequest(goal=goal, start=start or {}, obstacles=(table,),
                         attached=(AttachedObject(case.box, case.link),), seed=3,
                         planning_time=5.0)


def test_a_resting_box_is_lifted_by_a_line_then_moved(case):
    table = _table_under(case)
    q0 = np.zeros(len(case.names))
    # it rests: it touches the table (FCL says they collide, its bottom on the top)
    assert _gap(case, q0, table) <= 0.0
    up = case.mp.solve(_request(case, LineGoal(offset=(0.0, 0.0, 0.03)), table))
    v = up.verification
    assert v.ok and v.certified and v.collision_free
    assert up.lifted_off == (("carried_box", "table"),)
    qs = np.asarray(up.trajectory.positions)
    # never deeper than DEPTH into the table, and clear of it at the end
    assert _depth_hits(case, qs, table, DEPTH) == 0
    assert _gap(case, qs[-1], table) > TOUCHING
    assert _box_hits(case.d, case.names, qs[-1:], case.box, case.link, table) == 0
    # from the lifted state, any move: the pair is checked again
    lifted = dict(zip(case.names, map(float, qs[-1])))
    move = case.mp.solve(_request(case, JointGoal({case.names[0]: 0.5}), table,
                                  start=lifted))
    assert move.verification.ok and move.verification.certified
    assert move.lifted_off == ()
    assert _box_hits(case.d, case.names, np.asarray(move.trajectory.positions), case.box,
                     case.link, table) == 0


def test_a_move_from_the_resting_start_is_refused_with_the_hint(case):
    table = _table_under(case)
    with pytest.raises(StartInCollision) as e:
        case.mp.solve(_request(case, JointGoal({case.names[0]: 0.5}), table))
    d = e.value.details
    assert d["resting"] == [["carried_box", "table"]]
    assert "'carried_box' rests on 'table': lift it first with a straight line" in d["hint"]
    assert '{"line": {"offset": [0, 0, 0.05]}}' in e.value.message
    assert ["carried_box", "table"] in d["pairs"]


def test_a_line_along_the_table_is_refused_naming_the_pair(case):
    table = _table_under(case)
    with pytest.raises(GoalInCollision) as e:
        case.mp.solve(_request(case, LineGoal(offset=(0.02, 0.0, 0.0)), table))
    assert e.value.pairs == [("carried_box", "table")]
    assert "still on 'table'" in e.value.message and "lift it clear" in e.value.message
    # the refused end really is on the table: an independent check
    q_end = np.array([e.value.details["q"][n] for n in case.names])
    assert _gap(case, q_end, table) <= TOUCHING


def test_a_line_down_runs_into_the_table_core(case):
    table = _table_under(case)
    with pytest.raises(LineInterrupted) as e:
        case.mp.solve(_request(case, LineGoal(offset=(0.0, 0.0, -0.03)), table))
    assert e.value.details["pairs"] == [["carried_box", "table.core"]]
    assert e.value.fraction < 0.5


def test_a_box_stuck_in_the_table_does_not_rest_on_it(case):
    table = _table_under(case, sink=3 * TOUCHING)  # 3 mm into it
    with pytest.raises(StartInCollision) as e:
        case.mp.solve(_request(case, LineGoal(offset=(0.0, 0.0, 0.03)), table))
    assert "resting" not in e.value.details
    assert ["carried_box", "table"] in e.value.details["pairs"]


def test_a_check_names_the_resting_pair_and_not_a_stuck_one(case):
    import json

    from arduinobot.client.replies import CheckReply
    from arduinobot.contract import wire
    from arduinobot.service.plan.handlers import Handlers

    h = Handlers(case.d)

    def check(table: Obstacle, q0: float) -> dict:
        data = {"joints": {case.names[0]: q0}, "obstacles": [table.to_json()],
                "attached": [AttachedObject(case.box, case.link).to_mapping()]}
        return h.check(wire.decode("check", json.dumps(data)))

    rests = check(_table_under(case), 0.0)
    assert not rests["valid"] and rests["resting"] == [["carried_box", "table"]]
    assert "lift it first with a straight line" in rests["hint"]
    parsed = CheckReply.parse({**rests, "request_id": "r"})  # the schema, then the type
    assert parsed.resting == (("carried_box", "table"),) and parsed.hint == rests["hint"]
    stuck = check(_table_under(case, sink=3 * TOUCHING), 0.0)
    assert not stuck["valid"] and "resting" not in stuck and "hint" not in stuck
    assert "resting" not in check(_table_under(case), 0.8)  # swung away: free


def test_a_box_on_the_floor_is_lifted_off_it(case):
    # a floor of the user's own at the box's bottom (the id ``ground`` replaces ours; a
    # small one, clear of the arm)
    table = _table_under(case)
    top = table.xyz[2] + THICK / 2
    floor = Obstacle("ground", "box", size=(0.5, 0.5, 0.2),
                     xyz=(table.xyz[0], table.xyz[1], top - 0.1))
    with pytest.raises(StartInCollision) as e:
        case.mp.solve(_request(case, JointGoal({case.names[0]: 0.5}), floor))
    assert e.value.details["resting"] == [["carried_box", "ground"]]
    up = case.mp.solve(_request(case, LineGoal(offset=(0.0, 0.0, 0.03)), floor))
    assert up.verification.ok and up.verification.certified
    qs = np.asarray(up.trajectory.positions)
    assert _depth_hits(case, qs, floor, DEPTH) == 0
    assert _gap(case, qs[-1], floor) > TOUCHING


def test_a_support_too_thin_to_prove_the_lift_against_is_refused(case):
    thick = _table_under(case)
    thin = Obstacle("table", "box", size=(0.5, 0.5, 0.003),  # 3 mm: no 2 mm core
                    xyz=(thick.xyz[0], thick.xyz[1], thick.xyz[2] + THICK / 2 - 0.0015))
    with pytest.raises(StartInCollision) as e:
        case.mp.solve(_request(case, LineGoal(offset=(0.0, 0.0, 0.03)), thin))
    assert "'table' has no core to prove the lift against" in e.value.message


def test_a_core_takes_an_id_clear_of_the_scene_s(case):
    table = _table_under(case)
    other = Obstacle("table.core", "sphere", radius=0.01, xyz=(3.0, 3.0, 3.0))
    req = _request(case, LineGoal(offset=(0.0, 0.0, -0.03)), table)
    with pytest.raises(LineInterrupted) as e:
        case.mp.solve(MotionRequest(goal=req.goal, start={}, obstacles=(table, other),
                                    attached=req.attached, seed=3))
    assert e.value.details["pairs"] == [["carried_box", "table.core_"]]


def test_a_running_lift_is_rechecked_in_its_own_world(case):
    # the execute wing's recheck of a lift's rest: certified with the pair allowed and
    # the table's core checked, as it was planned; a rest that stays on the table is not
    from arduinobot.service.plan.handlers import Handlers
    from arduinobot.service.plan.recheck import recheck

    table = _table_under(case)
    up = case.mp.solve(_request(case, LineGoal(offset=(0.0, 0.0, 0.03)), table))
    qs = np.asarray(up.trajectory.positions)
    h = Handlers(case.d)
    data = {"joint_names": list(up.trajectory.joint_names), "obstacles": [table.to_json()],
            "attached": [AttachedObject(case.box, case.link).to_mapping()]}
    assert recheck(h, {**data, "positions": qs.tolist()}, scene=None)["certified"]
    stays = recheck(h, {**data, "positions": [qs[0].tolist()] * 3}, scene=None)
    assert not stays["certified"] and stays["safe"] == -1
    assert sorted(stays["refused"]["pair"]) == ["carried_box", "table"]
    # a rest that presses the box 1 cm into the table, then lifts it clear: it ends
    # clear, so the pair is allowed, and the table's core refuses it
    down = case.mp.solve(_request(case, LineGoal(offset=(0.0, 0.0, -0.01)), table,
                                  start=dict(zip(case.names, map(float, qs[-1])))))
    deeper = np.asarray(down.trajectory.positions)
    dq = deeper[-1] - deeper[0]
    pushed = np.vstack([qs[0] + np.outer(np.linspace(0, 1, 20), dq), qs[-1:]])
    got = recheck(h, {**data, "positions": pushed.tolist()}, scene=None)
    assert not got["certified"]
    assert sorted(got["refused"]["pair"]) == ["carried_box", "table.core"]
