"""A running task's rest certified piece by piece, each in its own step's world
(service/plan/task_recheck.py): the carried object of a piece is checked, the kept
scene's copy of an object the task moves is not, an allowed pair is not; the refusal
names the piece. The swing of tests/helpers/carry.py: free for the bare arm, through the
table with the box hanging below the tool."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.state import SceneSnapshot
from arduinobot.service.plan.handlers import Handlers
from tests.helpers.carry import shipped_case

case = pytest.fixture(shipped_case, scope="module", name="case")


@pytest.fixture(scope="module")
def handlers(case):
    return Handlers(case.d)


def _swing(case, n: int = 120) -> list[list[float]]:
    """The direct swing of joint 1 from the case's start to its goal (one tick apart)."""
    a, b = case.q(case.start), case.q(case.goal.values)
    return (a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)).tolist()


def _piece(qs, *, attached=(), allowed=(), obstacles=()):
    return {"positions": qs, "attached": [a.to_mapping() for a in attached],
            "allowed": [list(p) for p in allowed],
            "obstacles": [o.to_json() for o in obstacles]}


def _check(handlers, case, pieces, *, scene, moved=()):
    return handlers.handle("recheck", {"joint_names": case.names, "pieces": pieces,
                                       "moved": list(moved)}, scene=scene)


def test_each_piece_is_checked_with_what_the_task_carries_there(handlers, case):
    scene = SceneSnapshot(3, (case.table,))
    qs = _swing(case)
    bare = _check(handlers, case, [_piece(qs), _piece(qs[::-1])], scene=scene)
    assert bare["certified"] is True and bare["scene_revision"] == 3
    assert bare["states"] == 2 * len(qs)
    # the second piece carries the box (after an attach): it is refused there, with the
    # carried box and the kept scene's table as the pair
    got = _check(handlers, case, [_piece(qs), _piece(qs[::-1], attached=[case.attached()])],
                 scene=scene)
    assert got["certified"] is False and got["piece"] == 1
    assert sorted(got["refused"]["pair"]) == sorted(["carried_box", "table"])
    k = got["refused"]["state"]
    assert 0 < k < len(qs) - 1 and -1 <= got["safe"] <= k
    # the box resting on the table there (an allowed pair): certified
    ok = _check(handlers, case, [_piece(qs), _piece(qs[::-1], attached=[case.attached()],
                                                    allowed=[("carried_box", "table")])],
                scene=scene)
    assert ok["certified"] is True


def test_the_kept_copy_of_an_object_the_task_moves_is_left_out(handlers, case):
    # the carried box sweeps through the table; were the table an object the task
    # moves (picked, placed), the kept scene's copy is not where the task has it
    scene = SceneSnapshot(5, (case.table,))
    qs = _swing(case)
    carried = [case.attached()]
    kept = _check(handlers, case, [_piece(qs, attached=carried)], scene=scene)
    assert kept["certified"] is False
    moved = _check(handlers, case, [_piece(qs, attached=carried)], scene=scene,
                   moved=["table"])
    assert moved["certified"] is True
    # the task's own copy (where the task has it at that step) is checked
    back = _check(handlers, case, [_piece(qs, attached=carried, obstacles=[case.table])],
                  scene=scene, moved=["table"])
    assert back["certified"] is False and back["piece"] == 0


def test_a_piece_of_the_wrong_shape_is_refused_naming_it(handlers, case):
    with pytest.raises(InvalidRequest) as e:
        _check(handlers, case, [_piece(_swing(case)), _piece([[0.0, 0.0]])],
               scene=None)
    assert e.value.details["field"] == "pieces[1].positions"


def test_a_piece_naming_a_file_of_the_server_is_refused(handlers, case):
    # the pieces come back on the wire (the execute request): a mesh path is refused
    # before anything looks at the file
    mesh = {"id": "m", "shape": "mesh", "mesh_path": "/etc/passwd", "xyz": [0, 0, 0]}
    with pytest.raises(InvalidRequest) as e:
        _check(handlers, case, [{**_piece(_swing(case)), "obstacles": [mesh]}], scene=None)
    assert e.value.details["field"].startswith("pieces[0].obstacles[0]")
    held = {"object": mesh, "link": case.link}
    with pytest.raises(InvalidRequest) as e:
        _check(handlers, case, [{**_piece(_swing(case)), "attached": [held]}], scene=None)
    assert e.value.details["field"].startswith("pieces[0].attached[0].object")
