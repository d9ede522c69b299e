"""Kept-scene meshes take no disk they are not used for (issue 39, item 6): a refused
apply leaves none of its mesh files behind (50 refused, 0 files), a removed or cleared
mesh's file goes once no scene this instance may still plan against uses it, and a
scene's mesh folder is its own (collecting one scene's never touches another's)."""

from __future__ import annotations

import base64
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import trimesh
import zenoh

from arduinobot.contract.zconfig import zenoh_config
from arduinobot.description import load_description
from arduinobot.service.scene.file import mesh_dir_for
from arduinobot.service.scene.sync import SceneService
from tests.helpers.serve import free_port


def _mesh(oid: str, extents: float) -> dict[str, Any]:
    stl = trimesh.creation.box(extents=(extents,) * 3).export(file_type="stl")
    return {"id": oid, "shape": "mesh", "xyz": [1.5, 1.5, 1.5],
            "mesh": {"format": "stl", "data": base64.b64encode(stl).decode()}}


@pytest.fixture
def scene(tmp_path: Path) -> Iterator[SceneService]:
    session = zenoh.open(zenoh_config(mode="peer", listen=[f"tcp/127.0.0.1:{free_port()}"]))
    links = tuple(load_description().robot.links)
    svc = SceneService(session, "arduinobot", "a", links,
                       scene_file=tmp_path / "a" / "scene.json")
    svc.start()
    try:
        yield svc
    finally:
        svc.close()
        session.close()


def _apply(svc: SceneService, change: dict[str, Any]) -> dict[str, Any]:
    reply = next(iter(svc.session.get("arduinobot/scene/apply", payload=json.dumps(change))))
    if reply.ok is not None:
        return json.loads(reply.ok.payload.to_bytes())
    return json.loads(reply.err.payload.to_bytes())


def _files(svc: SceneService) -> list[str]:
    d = svc.builder.mesh_dir
    return sorted(p.name for p in d.iterdir()) if d.is_dir() else []


def test_refused_mesh_applies_leave_no_files(scene: SceneService) -> None:
    box = {"id": "twice", "shape": "box", "size": [0.1, 0.1, 0.1], "xyz": [1, 1, 1]}
    for i in range(50):
        # the mesh is decoded and written, then the apply is refused at add[2]
        body = _apply(scene, {"add": [_mesh(f"m{i}", 0.05 + 0.001 * i), box, box]})
        assert body["error"]["details"]["field"] == "add[2].id", body
    assert scene.state.revision == 0
    assert _files(scene) == []


def test_a_removed_mesh_file_goes_one_scene_later(scene: SceneService) -> None:
    assert _apply(scene, {"add": [_mesh("part", 0.1)]})["revision"] == 1
    (kept,) = _files(scene)
    assert _apply(scene, {"clear": True})["revision"] == 2
    # a plan that took revision 1 may still be reading it
    assert _files(scene) == [kept]
    assert _apply(scene, {"add": [_mesh("other", 0.2)]})["revision"] == 3
    (other,) = _files(scene)
    assert other != kept
    assert scene.state.objects[0].obstacle.geometry.source.name == other


def _big_stl() -> bytes:
    """A binary STL of 41,000 triangles (2,050,084 bytes: near the 2 MiB mesh cap)."""
    sphere = trimesh.creation.icosphere(subdivisions=6)
    return trimesh.Trimesh(0.1 * sphere.vertices, sphere.faces[:41_000],
                           process=False).export(file_type="stl")


def test_the_scenes_inline_meshes_are_capped_before_they_are_parsed(
        scene: SceneService) -> None:
    """Issue 39, item 10: the serving process keeps each mesh's text with its object, so
    mesh churn grew it with the scene. 16 meshes of 2 MB fit MAX_SCENE_MESH_BYTES (32
    MiB); a 17th is refused naming its field, before its bytes are parsed (they are no
    mesh at all), nothing changes, and the scene keeps taking changes."""
    from arduinobot.contract.caps import MAX_SCENE_MESH_BYTES
    data = base64.b64encode(_big_stl()).decode()
    near = [{"id": f"m{i}", "shape": "mesh", "xyz": [1.5, 1.5, 1.5 + i],
             "mesh": {"format": "stl", "data": data}} for i in range(16)]
    assert _apply(scene, {"add": near})["revision"] == 1
    files = _files(scene)
    junk = {"id": "junk", "shape": "mesh", "xyz": [1, 1, 1], "mesh": {
        "format": "stl", "data": base64.b64encode(bytes(2_000_000)).decode()}}
    body = _apply(scene, {"add": [junk]})
    err = body["error"]
    assert err["code"] == "INVALID_REQUEST" and err["details"]["field"] == "add[0].mesh.data"
    assert err["details"]["limit"] == MAX_SCENE_MESH_BYTES
    assert err["details"]["scene_bytes"] == 16 * 2_050_084
    assert err["details"]["size"] == 2_000_000
    assert scene.state.revision == 1 and _files(scene) == files
    # the same over the cap within one apply, at the object that passes it
    body = _apply(scene, {"clear": True, "add": [*near, junk]})
    assert body["error"]["details"]["field"] == "add[16].mesh.data", body
    # room made in the same apply: taken; the service still serves
    other = _mesh("small", 0.1)
    assert _apply(scene, {"remove": ["m0"], "add": [other]})["revision"] == 2
    assert len(scene.state.objects) == 16


def test_each_scene_file_has_its_own_mesh_folder(tmp_path: Path) -> None:
    a, b = tmp_path / "scene-a.json", tmp_path / "scene-b.json"
    assert mesh_dir_for(a) != mesh_dir_for(b)
    assert mesh_dir_for(a).parent == mesh_dir_for(b).parent == tmp_path / "meshes"


def test_a_killed_writers_temporary_files_go_at_start(tmp_path: Path) -> None:
    from arduinobot.service.scene.file import STALE_TMP_AGE, SceneFile

    path = tmp_path / "scene.json"
    path.write_text('{"revision": 0, "objects": [], "attached": []}')
    old = tmp_path / ".scene.json-abc123.tmp"   # a kill -9 mid-write, long ago
    young = tmp_path / ".scene.json-def456.tmp"  # a live writer's, being written
    other = tmp_path / ".other.json-abc123.tmp"  # another scene file's
    for f in (old, young, other):
        f.write_text("{")
    long_ago = old.stat().st_mtime - 2 * STALE_TMP_AGE
    os.utime(old, (long_ago, long_ago))
    os.utime(other, (long_ago, long_ago))
    assert SceneFile(path).clean() == 1
    assert not old.exists() and young.exists() and other.exists() and path.exists()
