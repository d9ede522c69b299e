"""Two scenes made apart at the same revision are told apart and reconciled (issue 39:
"after a restart both instances report revision 3 with different objects, permanently").
Two kept scenes (SceneService, each with its liveliness token as serve declares it) on
real Zenoh sessions behind a router on loopback; each starts from its own file at
revision 3, with different objects, as two instances leave them after a partition."""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import zenoh

from arduinobot.client.replies import SceneReply
from arduinobot.contract.zconfig import zenoh_config
from arduinobot.description import load_description
from arduinobot.service.scene.identity import encode_scene
from arduinobot.service.scene.sync import SceneService
from tests.helpers.serve import free_port

LINKS = tuple(load_description().robot.links)


def _box(oid: str, x: float) -> dict:
    return {"id": oid, "shape": "box", "size": [0.1, 0.1, 0.1], "xyz": [x, 1.0, 1.0],
            "rpy": [0.0, 0.0, 0.0]}


def _file(root: Path, name: str, *objects: dict) -> Path:
    path = root / name / "scene.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"revision": 3, "objects": list(objects), "attached": []}))
    return path


@contextmanager
def _cluster() -> Iterator:
    port = free_port()
    router = zenoh.open(zenoh_config(mode="router", listen=[f"tcp/127.0.0.1:{port}"]))
    held: list = []

    def member(name: str, path: Path) -> SceneService:
        s = zenoh.open(zenoh_config(mode="client", connect=[f"tcp/127.0.0.1:{port}"]))
        token = s.liveliness().declare_token(f"arduinobot/alive/{name}")
        svc = SceneService(s, "arduinobot", name, LINKS, scene_file=path)
        held.append((s, token, svc))
        svc.start()
        return svc

    member.endpoint = f"tcp/127.0.0.1:{port}"  # type: ignore[attr-defined]
    try:
        yield member
    finally:
        for s, token, svc in reversed(held):
            svc.close()
            token.undeclare()
            s.close()
        router.close()


def _digest(svc: SceneService) -> str:
    reply = SceneReply.parse(json.loads(svc.encoded()))  # the client reads it as sent
    assert reply.revision == svc.state.revision
    return json.loads(svc.encoded())["digest"]


def test_the_same_revision_with_other_objects_has_another_digest(tmp_path):
    a = encode_scene(_restored(_file(tmp_path, "a", _box("table", 1.0))))
    b = encode_scene(_restored(_file(tmp_path, "b", _box("ball", 1.5))))
    again = encode_scene(_restored(tmp_path / "a" / "scene.json"))
    assert a[1] != b[1] and a == again


def _restored(path: Path):
    from arduinobot.scene.state import SceneBuilder, restore
    return restore(json.loads(path.read_text()), SceneBuilder(LINKS, path.parent / "meshes"))


def test_a_starting_follower_takes_the_leaders_scene_at_the_same_revision(tmp_path):
    with _cluster() as member:
        leader = member("a", _file(tmp_path, "a", _box("table", 1.0)))
        follower = member("b", _file(tmp_path, "b", _box("ball", 1.5)))
        assert follower.state.revision == 3 and follower.state.ids() == ("table",)
        assert _digest(follower) == _digest(leader)
        kept = json.loads((tmp_path / "b" / "scene.json").read_text())
        assert [o["id"] for o in kept["objects"]] == ["table"]  # on its disk too


def test_a_follower_apart_takes_the_leaders_scene_with_its_next_change(tmp_path):
    with _cluster() as member:
        follower = member("b", _file(tmp_path, "b", _box("ball", 1.5)))
        leader = member("a", _file(tmp_path, "a", _box("table", 1.0)))
        assert leader.state.ids() == ("table",) and follower.state.ids() == ("ball",)
        # through the follower (its own key, from a client's session): forwarded to the leader
        with zenoh.open(zenoh_config(mode="client", connect=[member.endpoint])) as client:
            reply = next(iter(client.get("arduinobot/instance/b/scene/apply",
                                         payload=json.dumps({"add": [_box("cup", 0.5)]}))))
        body = json.loads((reply.ok or reply.err).payload.to_bytes())
        assert body.get("revision") == 4 and "not_taken_by" not in body, body
        assert leader.state.ids() == ("table", "cup")
        assert follower.state.revision == 4 and follower.state.ids() == ("table", "cup")
        assert _digest(follower) == _digest(leader)
