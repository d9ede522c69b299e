"""A kept scene file that cannot be read (issue 39, item 10): alone, the instance stops
naming the file, the object and the field (a scene silently emptied would lose its
objects); with a live instance of its prefix, it starts from that instance's scene and
sets the file aside for its owner to read. In process: SceneService on real Zenoh
sessions on loopback (multicast scouting off)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import zenoh

from arduinobot.contract.errors import InvalidRequest
from arduinobot.contract.zconfig import zenoh_config
from arduinobot.description import load_description
from arduinobot.service.scene.sync import SceneService
from tests.helpers.serve import free_port
from tests.service.test_scene_meshes import _apply

LINKS = tuple(load_description().robot.links)
TABLE = {"id": "table", "shape": "box", "size": [0.5, 0.5, 0.05], "xyz": [0.0, 1.0, 0.3]}
BALL = {"id": "ball", "shape": "sphere", "radius": -1.0, "xyz": [0.0, 1.0, 1.0]}


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.mark.parametrize("text, field, obj", [
    (json.dumps({"revision": 3, "objects": [TABLE, BALL]}), "objects[1].radius",
     "object 'ball' (objects[1])"),
    ('{"revision": 3, "objects": [', None, None),  # a file cut short
])
def test_alone_it_stops_naming_the_file_the_object_and_the_field(tmp_path, text, field, obj):
    path = _write(tmp_path / "scene.json", text)
    session = zenoh.open(zenoh_config(mode="peer", listen=[f"tcp/127.0.0.1:{free_port()}"]))
    svc = SceneService(session, "arduinobot", "a", LINKS, scene_file=path)
    try:
        with pytest.raises(InvalidRequest) as e:
            svc.start()
    finally:
        svc.close()
        session.close()
    msg = str(e.value)
    assert str(path) in msg and "cannot be read" in msg and "--scene-file" in msg
    assert e.value.details["field"] == field and e.value.details["object"] == obj
    if obj is not None:
        assert obj in msg and "radius" in msg
    assert path.read_text() == text  # untouched: its owner decides


def test_with_a_live_instance_it_starts_from_its_scene_and_sets_the_file_aside(tmp_path):
    port = free_port()
    router = zenoh.open(zenoh_config(mode="router", listen=[f"tcp/127.0.0.1:{port}"]))
    sessions, services = [], []

    def member(name: str, path: Path) -> SceneService:
        s = zenoh.open(zenoh_config(mode="client", connect=[f"tcp/127.0.0.1:{port}"]))
        sessions.append(s)
        svc = SceneService(s, "arduinobot", name, LINKS, scene_file=path)
        services.append(svc)
        svc.start()
        return svc

    try:
        first = member("a", tmp_path / "a" / "scene.json")
        body = _apply(first, {"add": [TABLE]})
        assert body["revision"] == 1, body
        bad = _write(tmp_path / "b" / "scene.json",
                     json.dumps({"revision": 7, "objects": [TABLE, BALL]}))
        second = member("b", bad)
        assert second.state.revision == 1 and second.state.ids() == ("table",)
        aside = list(bad.parent.glob("scene.json.unreadable-*"))
        assert len(aside) == 1 and json.loads(aside[0].read_text())["revision"] == 7
        kept = json.loads(bad.read_text())  # the live scene, kept in its place
        assert kept["revision"] == 1 and [o["id"] for o in kept["objects"]] == ["table"]
    finally:
        for svc in reversed(services):
            svc.close()
        for s in sessions:
            s.close()
        router.close()
