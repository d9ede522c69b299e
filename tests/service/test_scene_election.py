"""The kept scene's leader is elected among the instances that answer, not among any
liveliness token (issue 39: "a fake token makes every apply BUSY after 10 s").
Two kept scenes (SceneService, each with its liveliness token as serve declares it) on
real Zenoh sessions behind a router on loopback, with no ACL (as a service's own
credentials allow); the fake or hung instance is another session with a smaller id."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import zenoh

from arduinobot.contract.zconfig import zenoh_config
from arduinobot.description import load_description
from arduinobot.service.scene.sync import SceneService
from tests.helpers.serve import free_port

LINKS = tuple(load_description().robot.links)


def _box(oid: str, x: float) -> dict:
    return {"id": oid, "shape": "box", "size": [0.1, 0.1, 0.1], "xyz": [x, 1.0, 1.0],
            "rpy": [0.0, 0.0, 0.0]}


@contextmanager
def _cluster(tmp: Path) -> Iterator:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router = zenoh.open(zenoh_config(mode="router", listen=[endpoint]))
    held: list = []

    def session() -> zenoh.Session:
        s = zenoh.open(zenoh_config(mode="client", connect=[endpoint]))
        held.append((s, None, None))
        return s

    def member(name: str) -> SceneService:
        s = zenoh.open(zenoh_config(mode="client", connect=[endpoint]))
        svc = SceneService(s, "arduinobot", name, LINKS, scene_file=tmp / name / "scene.json")
        svc.start()  # serve declares its alive token once the scene has started
        token = s.liveliness().declare_token(f"arduinobot/alive/{name}")
        held.append((s, token, svc))
        return svc

    member.session = session  # type: ignore[attr-defined]
    try:
        yield member
    finally:
        for s, token, svc in reversed(held):
            if svc is not None:
                svc.close()
            if token is not None:
                token.undeclare()
            s.close()
        router.close()


def _apply(client: zenoh.Session, key: str, change: dict) -> dict:
    replies = list(client.get(key, payload=json.dumps(change), timeout=30.0))
    assert replies, f"no reply on {key}"
    r = replies[0]
    return json.loads((r.ok or r.err).payload.to_bytes())


def _applies_through_both(member) -> tuple[SceneService, SceneService]:
    a, b = member("a"), member("b")
    client = member.session()
    first = _apply(client, "arduinobot/instance/a/scene/apply", {"add": [_box("cup", 0.5)]})
    second = _apply(client, "arduinobot/instance/b/scene/apply", {"add": [_box("jar", 0.7)]})
    assert first.get("revision") == 1 and first.get("leader") == "a", first
    assert second.get("revision") == 2 and second.get("leader") == "a", second
    assert "not_taken_by" not in first and "not_taken_by" not in second
    for svc in (a, b):
        assert svc.state.revision == 2 and svc.state.ids() == ("cup", "jar")
    return a, b


def test_a_token_that_is_no_instance_does_not_lead(tmp_path):
    """A liveliness token `alive/0` (smaller than every real id) declared by a session
    that serves nothing: it led before, and every apply waited 10 s then BUSY."""
    with _cluster(tmp_path) as member:
        fake = member.session()
        token = fake.liveliness().declare_token("arduinobot/alive/0")
        try:
            a, b = _applies_through_both(member)
            assert "0" in a.instances.live() and "0" in b.instances.live()
        finally:
            token.undeclare()


def test_a_hung_instance_does_not_lead(tmp_path):
    """`alive/0` with a `scene/ready` queryable that takes the query and never answers (a
    hung process, a VM paused within Zenoh's lease): passed over after 0.5 s."""
    with _cluster(tmp_path) as member:
        hung = member.session()
        taken: list = []
        done = threading.Event()

        def never(query):
            taken.append(query)  # kept unanswered until the test ends
            done.wait(30)
        q = hung.declare_queryable("arduinobot/instance/0/scene/ready", never)
        token = hung.liveliness().declare_token("arduinobot/alive/0")
        try:
            _applies_through_both(member)
            assert taken  # it was asked, and did not answer
        finally:
            done.set()
            token.undeclare()
            q.undeclare()


def test_an_instance_that_does_not_lead_refuses_to_and_names_the_leader(tmp_path):
    """Two views of the leader for a moment (one instance passed the leader over, the
    other did not) still make one writer: a `scene/lead` sent to an instance that is not
    the leader is refused naming it, and nothing changes there."""
    with _cluster(tmp_path) as member:
        a, b = member("a"), member("b")
        client = member.session()
        body = _apply(client, "arduinobot/instance/b/scene/lead",
                      {"add": [_box("cup", 0.5)], "apply_id": "t-1"})
        assert body["error"]["code"] == "BUSY", body
        assert body["error"]["details"] == {"reason": "not_leader", "leader": "a"}
        assert a.state.revision == b.state.revision == 0


def test_a_stopped_instance_does_not_lead_until_it_has_caught_up(tmp_path):
    """A process found stopped (the watch's gap) answers it is not ready and refuses to
    lead; its catch-up makes it ready again."""
    with _cluster(tmp_path) as member:
        a, b = member("a"), member("b")
        client = member.session()
        a._stalled = True  # as _was_stopped sets it, without its catch-up yet
        assert b.leader() == "b" and not a.election.ready()
        body = _apply(client, "arduinobot/instance/b/scene/apply", {"add": [_box("cup", 0.5)]})
        assert body.get("leader") == "b" and body.get("revision") == 1, body
        assert a.state.ids() == ("cup",)  # it still takes the leader's changes
        a._was_stopped(5.0)  # its catch-up runs on its sync thread
        for _ in range(200):
            if a.election.ready():
                break
            threading.Event().wait(0.05)
        assert a.election.ready()
        a.election.reconsider("a")
        b.election.reconsider("a")
        body = _apply(client, "arduinobot/instance/b/scene/apply", {"add": [_box("jar", 0.7)]})
        assert body.get("leader") == "a" and body.get("revision") == 2, body
        assert a.state.ids() == b.state.ids() == ("cup", "jar")
