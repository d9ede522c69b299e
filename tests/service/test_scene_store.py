"""The kept scene without a service: meshes, applies (all or nothing), the file, the
schemas, and plans against a scene (arduinobot.scene.mesh_codec, arduinobot.scene.state)."""

from __future__ import annotations

import base64
import json

import numpy as np
import pytest
import trimesh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest, PlanningError, SceneConflict
from arduinobot.scene.builder import SceneBuilder
from arduinobot.scene.change import apply, restore
from arduinobot.scene.mesh_codec import (
    MAX_MESH_BASE64,
    MAX_MESH_BYTES,
    MAX_MESH_TRIANGLES,
    decode_mesh,
)
from arduinobot.scene.state import MAX_SCENE_OBJECTS, SceneSnapshot, SceneState, with_scene
from arduinobot.service.scene.apply import MAX_APPLY_PAYLOAD, decode_apply
from arduinobot.service.scene.file import SceneFile
from tests.helpers.scene_fuzz import binary_stl as _binary_stl
from tests.helpers.scene_fuzz import junk_mesh as _junk_mesh
from tests.helpers.scene_fuzz import mutate as _mutate

LINKS = ("base_link", "claw_support")


def b64(data: bytes | str) -> str:
    return base64.b64encode(data.encode() if isinstance(data, str) else data).decode()


def stl_box(extents=(0.1, 0.2, 0.3)) -> bytes:
    return trimesh.creation.box(extents=extents).export(file_type="stl")


def mesh_obj(oid: str, data: bytes | str, fmt: str = "stl", **extra) -> dict:
    return {"id": oid, "shape": "mesh", "mesh": {"format": fmt, "data": b64(data)}, **extra}


@pytest.fixture
def builder(tmp_path):
    return SceneBuilder(LINKS, tmp_path / "meshes")


def applied(state, change, builder):
    """apply() on a change as the service decodes it (schema included)."""
    return apply(state, decode_apply(json.dumps(change).encode()), builder)


# -- meshes ---------------------------------------------------------------------------

def test_binary_and_ascii_stl_and_obj_decode_scaled_and_content_keyed(builder):
    box = trimesh.creation.box(extents=(0.1, 0.2, 0.3))
    binary = decode_mesh({"format": "stl", "data": b64(box.export(file_type="stl"))},
                         scale=(2, 2, 2))
    ascii_ = decode_mesh({"format": "stl", "data": b64(box.export(file_type="stl_ascii"))},
                         scale=(2, 2, 2))
    obj = decode_mesh({"format": "obj", "data": b64(box.export(file_type="obj"))},
                      scale=(2, 2, 2))
    for m in (binary, ascii_, obj):
        ext = m.vertices.max(axis=0) - m.vertices.min(axis=0)
        np.testing.assert_allclose(ext, [0.2, 0.4, 0.6], atol=1e-6)
        assert len(m.faces) == 12
    # the same geometry, the same key; other geometry, another key
    assert binary.sha256 == ascii_.sha256
    other = decode_mesh({"format": "stl", "data": b64(box.export(file_type="stl"))})
    assert other.sha256 != binary.sha256
    path = binary.write(builder.mesh_dir)
    assert path.name == f"{binary.sha256}.stl" and path.read_bytes() == binary.stl
    assert binary.write(builder.mesh_dir) == path  # once


FLAT = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"
SLIVERS = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n"


@pytest.mark.parametrize("spec, scale, field, words", [
    ({"format": "stl", "data": "not base64!"}, 1, "add[0].mesh.data", "base64"),
    ({"format": "stl", "data": b64(b"solid x\nfacet nonsense")}, 1, "add[0].mesh", ""),
    # text that is no STL: not read as a binary header counting 1.7e9 triangles
    ({"format": "stl", "data": b64(b"a readme saved as .stl, " * 5)}, 1, "add[0].mesh",
     "not an STL mesh: neither text beginning with 'solid' nor a binary STL"),
    ({"format": "stl", "data": b64(b"not a mesh\n")}, 1, "add[0].mesh", "not an STL mesh"),
    ({"format": "obj", "data": b64(FLAT)}, 1, "add[0].mesh", "flat"),
    ({"format": "obj", "data": b64(SLIVERS)}, 1, "add[0].mesh", "area"),
    ({"format": "obj", "data": b64("v 0 0 0\n")}, 1, "add[0].mesh", "no triangles"),
    ({"format": "stl", "data": b64(stl_box())}, 1000, "add[0].mesh", "more than 100 m"),
    ({"format": "stl", "data": b64(stl_box())}, 1e308, "add[0].mesh", "more than 100 m"),
    # a header counting more triangles than the bytes hold (a whole binary STL over the
    # triangle cap is over the byte cap too): refused before parsing, as no STL
    ({"format": "stl", "data": b64(_binary_stl(np.zeros((1, 3, 3)), MAX_MESH_TRIANGLES + 1))},
     1, "add[0].mesh", "not an STL mesh"),
    ({"format": "stl", "data": b64(_binary_stl(np.array(
        [[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 0], [1, 0, 0], [0, 0, np.nan]],
         [[0, 0, 0], [0, 1, 0], [0, 0, 1]]], np.float32)))}, 1, "add[0].mesh", "non-finite"),
])
def test_bad_meshes_are_refused_naming_the_field(builder, spec, scale, field, words):
    state = applied(SceneState(), {"add": [{"id": "ok", "shape": "sphere", "radius": 0.1}]},
                    builder)
    with pytest.raises(InvalidRequest) as e:
        apply(state, {"add": [{"id": "m", "shape": "mesh", "mesh": spec, "scale": scale}]},
              builder)
    assert e.value.code == Code.INVALID_REQUEST and e.value.field == field
    assert words in e.value.message


def test_mesh_byte_cap_comes_before_decoding():
    big = "A" * (MAX_MESH_BASE64 + 4)
    with pytest.raises(InvalidRequest) as e:
        decode_mesh({"format": "stl", "data": big}, field="add[3].mesh")
    assert e.value.field == "add[3].mesh.data" and e.value.details["limit"] == MAX_MESH_BYTES
    with pytest.raises(InvalidRequest) as e:  # the schema says it too, over the wire
        decode_apply(json.dumps({"add": [mesh_obj("m", b"")]}).replace(
            '"data": ""', f'"data": "{big}"').encode())
    assert e.value.field == "add[0].mesh.data"


# -- applies --------------------------------------------------------------------------

def test_apply_clears_removes_adds_and_counts_revisions(builder):
    s1 = applied(SceneState(), {"add": [
        {"id": "table", "shape": "box", "size": [1, 1, 0.1], "xyz": [0, 1, 0.5]},
        mesh_obj("bin", stl_box(), scale=[1, 1, 2], xyz=[0.3, 0.8, 0.6])]}, builder)
    assert s1.revision == 1 and s1.ids() == ("table", "bin")
    mesh = s1.snapshot.obstacles[1]
    assert mesh.shape == "mesh" and mesh.xyz == (0.3, 0.8, 0.6)
    assert trimesh.load(mesh.mesh_path).extents[2] == pytest.approx(0.6)
    # the reply keeps what was sent (meshes as sent), and no carried objects
    assert s1.to_json()["objects"][1]["mesh"]["data"] == b64(stl_box())
    assert s1.to_json()["attached"] == []
    # replace in one apply: remove then add the same id
    s2 = applied(s1, {"remove": ["table"], "add": [{"id": "table", "shape": "sphere",
                                                    "radius": 0.2}], "if_revision": 1}, builder)
    assert s2.revision == 2 and s2.snapshot.obstacles[-1].shape == "sphere"
    s3 = applied(s2, {"clear": True, "add": [{"id": "x", "shape": "sphere", "radius": 1}]},
                 builder)
    assert s3.ids() == ("x",) and s3.revision == 3


@pytest.mark.parametrize("change, field, code", [
    ({"if_revision": 0}, "if_revision", Code.SCENE_CONFLICT),
    ({"remove": ["nothere"]}, "remove[0]", Code.INVALID_REQUEST),
    ({"remove": ["table", "table"]}, "remove[1]", Code.INVALID_REQUEST),
    ({"clear": True, "remove": ["table"]}, "remove[0]", Code.INVALID_REQUEST),
    ({"add": [{"id": "table", "shape": "sphere", "radius": 1}]}, "add[0].id",
     Code.INVALID_REQUEST),
    ({"add": [{"id": "a", "shape": "sphere", "radius": 1},
              {"id": "a", "shape": "sphere", "radius": 1}]}, "add[1].id", Code.INVALID_REQUEST),
    ({"add": [{"id": "base_link", "shape": "sphere", "radius": 1}]}, "add[0].id",
     Code.INVALID_REQUEST),
    ({"add": [{"id": "a", "shape": "sphere", "radius": 1, "frame": "claw_support"}]},
     "add[0].frame", Code.INVALID_REQUEST),
    ({"add": [{"id": "a", "shape": "sphere", "radius": 1, "frame": "moon"}]},
     "add[0].frame", Code.INVALID_REQUEST),
    ({"add": [{"id": "a", "shape": "sphere", "radius": 1}], "attach": [{"object": "a"}]},
     "attach[0]", Code.INVALID_REQUEST),  # the schema: no link
    ({"detach": ["table"]}, "detach", Code.INVALID_REQUEST),  # no robot model here
    ({"add": [{"id": "a", "shape": "mesh"}]}, "add[0]", Code.INVALID_REQUEST),
    ({"add": [{"id": "a", "shape": "box", "size": [1, 1, 1], "scale": 2}]}, "add[0]",
     Code.INVALID_REQUEST),
    ({"add": [{"id": "a", "shape": "box", "size": [1, 1, 1]}], "colour": 1}, "colour",
     Code.INVALID_REQUEST),
])
def test_refused_applies_are_coded_name_the_field_and_change_nothing(builder, change, field,
                                                                    code):
    state = applied(SceneState(), {"add": [{"id": "table", "shape": "box",
                                            "size": [1, 1, 0.1]}]}, builder)
    before = state.to_json()
    with pytest.raises(PlanningError) as e:
        applied(state, change, builder)
    assert e.value.code == code and e.value.details["field"] == field
    assert state.to_json() == before  # immutable: nothing to roll back
    if code == Code.SCENE_CONFLICT:
        assert e.value.details["current_revision"] == 1


def test_attach_without_a_robot_model_is_refused(builder):
    state = applied(SceneState(), {"add": [{"id": "a", "shape": "sphere", "radius": 1}]},
                    builder)
    with pytest.raises(InvalidRequest) as e:
        applied(state, {"attach": [{"object": "a", "link": "claw_support"}]}, builder)
    assert e.value.field == "attach"


def test_object_cap(builder):
    many = [{"id": f"s{i}", "shape": "sphere", "radius": 0.01} for i in range(200)]
    state = applied(SceneState(), {"add": many}, builder)
    more = [{"id": f"t{i}", "shape": "sphere", "radius": 0.01}
            for i in range(MAX_SCENE_OBJECTS - 200 + 1)]
    with pytest.raises(InvalidRequest) as e:
        applied(state, {"add": more}, builder)
    assert e.value.field == "add" and e.value.details["limit"] == MAX_SCENE_OBJECTS
    assert state.revision == 1 and len(state.objects) == 200


def test_apply_payload_caps():
    with pytest.raises(InvalidRequest) as e:
        decode_apply(b" " * (MAX_APPLY_PAYLOAD + 1))
    assert e.value.details["limit"] == MAX_APPLY_PAYLOAD
    with pytest.raises(InvalidRequest) as e:
        decode_apply(b'{"add": [' + b"[" * 20 + b"]" * 20 + b"]}")
    assert e.value.code == Code.INVALID_REQUEST
    for bad in (b"", b"{", b'{"clear": NaN}', b"[]"):
        with pytest.raises(InvalidRequest):
            decode_apply(bad)


# -- the file and restoring -----------------------------------------------------------

def test_file_round_trip_restores_every_object(builder, tmp_path):
    state = applied(SceneState(), {"add": [
        {"id": "table", "shape": "box", "size": [1, 1, 0.1], "xyz": [0, 1, 0.5]},
        mesh_obj("bin", stl_box(), scale=0.5)]}, builder)
    f = SceneFile(tmp_path / "state" / "scene.json")
    f.save(state)
    assert not [p for p in f.path.parent.iterdir() if p.name.endswith(".tmp")]
    back = restore(f.load(), SceneBuilder(LINKS, tmp_path / "other"))
    assert back.revision == 1 and back.to_json() == state.to_json()
    assert back.snapshot.obstacles[1].mesh_path.endswith(
        state.snapshot.obstacles[1].mesh_path.rsplit("/", 1)[1])
    assert SceneFile(tmp_path / "none.json").load() is None
    (tmp_path / "bad.json").write_text("{nope")
    with pytest.raises(InvalidRequest):
        SceneFile(tmp_path / "bad.json").load()


# -- schemas --------------------------------------------------------------------------

def test_scene_schemas_round_trip(builder):
    state = applied(SceneState(), {"add": [
        {"id": "t", "shape": "cylinder", "radius": 0.1, "length": 1, "frame": "world"},
        mesh_obj("m", stl_box(), fmt="stl", scale=[1, 1, 1], rpy=[0, 0, 1])]}, builder)
    body = json.loads(wire.encode(state.to_json()))
    wire.validator("scene_response").validate(body)
    wire.validator("scene_apply_response").validate({"revision": 1, "objects": 2})
    # what the scene holds applies again as it is (`arduinobot scene load`)
    again = decode_apply(wire.encode({"clear": True, "add": body["objects"],
                                      "if_revision": 1}))
    assert applied(state, again, builder).to_json()["objects"] == body["objects"]
    for name in ("plan_request", "check_request"):
        assert wire.schema(name)["properties"]["scene_revision"]["minimum"] == 0
    for name in ("plan_response", "check_response"):
        assert "scene_revision" in wire.schema(name)["properties"]


# -- plans against a scene ------------------------------------------------------------

def test_with_scene_merges_pins_and_refuses_shadowing(builder):
    from arduinobot.scene.obstacles import Obstacle
    state = applied(SceneState(), {"add": [{"id": "t", "shape": "sphere", "radius": 1}]},
                    builder)
    own = (Obstacle("mine", "sphere", radius=0.1),)
    obs, rev = with_scene(state.snapshot, {}, own)
    assert [o.id for o in obs] == ["t", "mine"] and rev == 1
    assert with_scene(state.snapshot, {"scene_revision": 1}, own)[1] == 1
    with pytest.raises(SceneConflict) as e:
        with_scene(state.snapshot, {"scene_revision": 0}, own)
    assert e.value.details == {"field": "scene_revision", "current_revision": 1}
    with pytest.raises(InvalidRequest) as e:
        with_scene(state.snapshot, {}, (Obstacle("t", "sphere", radius=0.1),))
    assert e.value.field == "obstacles[0].id"
    assert with_scene(None, {}, own) == (own, 0)
    assert with_scene(SceneSnapshot(0), {"scene_revision": 0}, ()) == ((), 0)


def test_a_plan_avoids_the_scene_and_names_its_revision(desc, builder):
    from arduinobot.contract.errors import StartInCollision
    from arduinobot.service.plan.handlers import Handlers
    h = Handlers(desc)
    state = applied(SceneState(), {"add": [mesh_obj("wall", stl_box((0.05, 2, 2)),
                                                    xyz=[0, 0.25, 0.5])]}, builder)
    free = h.check({"joints": {}}, scene=None)
    assert free["valid"] and free["scene_revision"] == 0
    hit = h.check({"joints": {}}, scene=state.snapshot)
    assert not hit["valid"] and hit["scene_revision"] == 1
    assert any("wall" in p for p in hit["pairs"])
    with pytest.raises(StartInCollision) as e:
        h.plan({"goal": {"named": "home"}}, scene=state.snapshot)
    assert ("base_link", "wall") in e.value.details["pairs"] or \
        ["base_link", "wall"] in e.value.details["pairs"]
    away = applied(state, {"clear": True, "add": [
        mesh_obj("far", stl_box(), xyz=[2, 2, 2])]}, builder)
    body = h.plan({"goal": {"named": "reach_left"}, "seed": 1}, scene=away.snapshot)
    assert body["scene_revision"] == 2 and body["duration"] > 0


# -- fuzz: whatever arrives, a coded refusal or a new scene, never another exception -----

def test_fuzzed_applies_are_coded_and_leave_the_scene_as_it_was(builder):
    import random
    r = random.Random(28)
    seed_state = applied(SceneState(), {"add": [TABLE_OBJ, mesh_obj("bin", stl_box())]},
                         builder)
    seeds = [{"add": [mesh_obj("m", stl_box(), scale=[1, 2, 3], rpy=[0, 0, 1])]},
             {"add": [mesh_obj("o", trimesh.creation.icosphere(1).export(file_type="obj"),
                               fmt="obj")], "remove": ["table"], "if_revision": 1},
             {"clear": True, "add": [{"id": "c", "shape": "cylinder", "radius": 0.1,
                                      "length": 1, "frame": "world"}]},
             {"remove": ["bin"], "attach": [], "detach": []}]
    before = seed_state.to_json()
    outcomes: dict[str, int] = {}
    for _ in range(3000):
        change = seeds[r.randrange(len(seeds))]
        for _ in range(r.randrange(1, 4)):
            change = _mutate(r, change)
        try:
            new = apply(seed_state, decode_apply(json.dumps(change).encode()), builder)
        except PlanningError as e:  # every refusal coded, naming where when it can
            assert e.code in (Code.INVALID_REQUEST, Code.SCENE_CONFLICT), e
            outcomes[e.code] = outcomes.get(e.code, 0) + 1
        else:
            assert new.revision == 2
            wire.validator("scene_response").validate(json.loads(wire.encode(new.to_json())))
            outcomes["applied"] = outcomes.get("applied", 0) + 1
        assert seed_state.to_json() == before
    assert outcomes.get("applied", 0) > 100 and outcomes[Code.INVALID_REQUEST] > 500, outcomes


def test_fuzzed_mesh_bytes_are_refused_or_read_never_crash():
    import random
    r = random.Random(5)
    refused = 0
    for _ in range(1500):
        fmt = r.choice(["stl", "obj"])
        try:
            m = decode_mesh({"format": fmt, "data": _junk_mesh(r)}, field="add[0].mesh")
        except InvalidRequest as e:
            assert e.field.startswith("add[0].mesh")
            refused += 1
        else:  # what is read is a bounded, finite solid
            assert np.isfinite(m.vertices).all() and 0 < len(m.faces) <= MAX_MESH_TRIANGLES
    assert refused > 1000


TABLE_OBJ = {"id": "table", "shape": "box", "size": [1, 1, 0.1], "xyz": [0, 1, 0.5]}
