"""Fair if_revision races (issue 39, item 10: one writer lost 400 races in a row): the
writer that loses a race gets the next turn. The races are played out in order, on a
real kept scene (SceneService on a Zenoh session on loopback) and through the Python
client; the turn's clock is the only thing a unit test steps by hand."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from arduinobot.client.client import PlannerClient
from arduinobot.client.errors import SceneConflict
from arduinobot.contract.zconfig import zenoh_config
from arduinobot.description import load_description
from arduinobot.service.scene.sync import SceneService
from arduinobot.service.scene.turns import TURN_TIME, Turns
from tests.helpers.serve import free_port
from tests.service.test_scene_meshes import _apply


def _box(oid: str, x: float = 1.0) -> dict:
    return {"id": oid, "shape": "box", "size": [0.1, 0.1, 0.1], "xyz": [x, 1.0, 1.0]}


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[SceneService, str]]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = zenoh.open(zenoh_config(mode="peer", listen=[endpoint]))
    svc = SceneService(session, "arduinobot", "a", tuple(load_description().robot.links),
                       scene_file=tmp_path / "scene.json")
    svc.start()
    try:
        yield svc, endpoint
    finally:
        svc.close()
        session.close()


def test_the_loser_of_a_race_goes_next(served):
    scene, _ = served
    assert _apply(scene, {"add": [_box("a0")]})["revision"] == 1
    # both read revision 1; B wins
    assert _apply(scene, {"add": [_box("b1")], "if_revision": 1})["revision"] == 2
    lost = _apply(scene, {"add": [_box("a1")], "if_revision": 1, "turn": "ask"})["error"]
    assert lost["code"] == "SCENE_CONFLICT" and lost["details"]["current_revision"] == 2
    turn = lost["details"]["turn"]
    assert lost["details"]["retry_within"] == TURN_TIME and turn in lost["message"]
    # B, faster, reads 2 and tries again: A holds the turn at 2
    held = _apply(scene, {"add": [_box("b2")], "if_revision": 2})["error"]
    assert held["code"] == "SCENE_CONFLICT" and held["details"]["reason"] == "turn_held"
    assert 0 < held["details"]["retry_after"] <= TURN_TIME
    assert "turn" not in held["details"]  # one turn at a time
    # an apply that does not race is never held up, and moves the scene on
    assert _apply(scene, {"add": [_box("c")]})["revision"] == 3
    stale = _apply(scene, {"add": [_box("a1")], "if_revision": 3, "turn": turn})
    assert stale["revision"] == 4  # the turn lapsed with revision 2: a plain apply at 3
    # A's turn used: the next race is open again
    assert _apply(scene, {"add": [_box("b2")], "if_revision": 4})["revision"] == 5
    assert scene.state.ids() == ("a0", "b1", "c", "a1", "b2")


def test_the_holder_goes_through_with_its_turn(served):
    scene, _ = served
    _apply(scene, {"add": [_box("x")], "if_revision": 0})
    turn = _apply(scene, {"add": [_box("y")], "if_revision": 0, "turn": "ask"})["error"][
        "details"]["turn"]
    assert _apply(scene, {"add": [_box("z")], "if_revision": 1})["error"]["details"][
        "reason"] == "turn_held"
    assert _apply(scene, {"add": [_box("y")], "if_revision": 1, "turn": turn})["revision"] == 2
    assert _apply(scene, {"add": [_box("z")], "if_revision": 2})["revision"] == 3


def test_a_turn_lapses_when_its_time_is_up():
    now = [100.0]
    turns = Turns(clock=lambda: now[0])
    asks = {"if_revision": 6, "turn": "ask"}
    assert turns.lost({"if_revision": 6}, 7) is None  # did not ask
    t = turns.lost(asks, 7)
    assert t is not None and turns.lost(asks, 7) is None  # one at a time
    assert turns.blocks({"if_revision": 7}, 7) == pytest.approx(TURN_TIME)
    assert turns.blocks({"add": []}, 7) is None  # no if_revision: never held up
    now[0] += TURN_TIME
    assert turns.blocks({"if_revision": 7}, 7) is None and turns.held(7) is None
    assert turns.lost(asks, 7) is not None  # the next loser's


def test_a_writer_that_does_not_ask_gets_no_turn_and_holds_nobody_up(served):
    scene, _ = served
    _apply(scene, {"add": [_box("x")], "if_revision": 0})
    lost = _apply(scene, {"add": [_box("y")], "if_revision": 0})["error"]
    assert lost["code"] == "SCENE_CONFLICT" and "turn" not in lost["details"]
    assert _apply(scene, {"add": [_box("z")], "if_revision": 1})["revision"] == 2


def test_two_clients_updating_in_a_loop_both_get_through(served):
    scene, endpoint = served
    rounds = 15
    done: dict[str, int] = {}
    errors: list[BaseException] = []
    start = threading.Barrier(2)

    def writer(name: str) -> None:
        try:
            with PlannerClient(endpoint, timeout=30) as c:
                start.wait()
                for i in range(rounds):
                    def change(s, i=i):  # needs the scene it was made from
                        return {"add": [_box(f"{name}{i}", 0.1 * len(s.objects))]}
                    c.update(change)
                    done[name] = i + 1
        except BaseException as e:  # reported below, with the thread's name
            errors.append(e)

    threads = [threading.Thread(target=writer, args=(n,)) for n in "AB"]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not errors, errors
    assert done == {"A": rounds, "B": rounds}
    assert scene.state.revision == 2 * rounds and len(scene.state.objects) == 2 * rounds


def test_update_gives_up_with_the_last_refusal(served):
    scene, endpoint = served
    with PlannerClient(endpoint, timeout=30) as c:
        def always_behind(s):
            _apply(scene, {"add": [_box(f"o{s.revision}")]})  # someone else, every time
            return {"add": [_box(f"mine{s.revision}")]}
        with pytest.raises(SceneConflict) as e:
            c.update(always_behind, attempts=3)
        assert e.value.details["current_revision"] == 3
        assert c.update(lambda s: None) is None
