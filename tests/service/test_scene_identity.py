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
from arduinobot.service.scene.identity import EncodedScenes, encode_scene, scene_digest
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
    assert json.loads(a)["digest"] != json.loads(b)["digest"] and a == again


def test_a_digest_hashed_member_by_member_is_the_whole_scenes(tmp_path):
    """The kept digests hash each member once; each must still be the digest of the whole
    scene as a fresh instance computes it, through a run of changes, order included."""
    from arduinobot.scene.builder import SceneBuilder
    from arduinobot.scene.change import apply
    builder = SceneBuilder(LINKS, tmp_path / "meshes")
    state = _restored(_file(tmp_path, "a", _box("table", 1.0), _box("ball", 1.5)))
    kept = EncodedScenes()
    changes = [{"add": [_box("cup", 0.5)]}, {"remove": ["ball"]},
               {"add": [_box("ball", 1.5)]}, {"remove": ["table"]},
               {"add": [_box("table", 1.0)]}]
    digests = [kept.digest(state)]
    for change in changes:
        state = apply(state, change, builder)
        digests.append(kept.digest(state))
        assert digests[-1] == scene_digest(state)
        assert json.loads(kept.of(state)[0])["digest"] == digests[-1]
    assert len(set(digests)) == len(digests)  # every revision its own
    # a fresh instance reading the scene's file has its digest; in another order, not
    body = state.to_json()
    for name, objects in (("same", body["objects"]), ("other", body["objects"][::-1])):
        path = tmp_path / name / "scene.json"
        path.parent.mkdir()
        path.write_text(json.dumps({**body, "objects": objects}))
        assert (scene_digest(_restored(path)) == digests[-1]) is (name == "same")


def _restored(path: Path):
    from arduinobot.scene.builder import SceneBuilder
    from arduinobot.scene.change import restore
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
