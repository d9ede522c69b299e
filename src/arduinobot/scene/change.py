"""How an apply changes the kept scene (:func:`apply`, all or nothing: the next
:class:`~arduinobot.scene.state.SceneState` or a refusal naming the field), and a scene
read back from its JSON form (:func:`restore`: a file, or another instance's reply)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from arduinobot.contract.caps import MAX_SCENE_MESH_BYTES
from arduinobot.contract.errors import InvalidRequest, SceneConflict
from arduinobot.scene.builder import SceneBuilder
from arduinobot.scene.frames import hold, warn_if_far
from arduinobot.scene.pose import rpy_of
from arduinobot.scene.state import MAX_SCENE_OBJECTS, WORLD, SceneAttached, SceneObject, SceneState


def apply(state: SceneState, change: Mapping[str, Any], builder: SceneBuilder, *,
          max_objects: int = MAX_SCENE_OBJECTS,
          max_mesh_bytes: int = MAX_SCENE_MESH_BYTES) -> SceneState:
    """The scene after ``change`` (a schema-valid apply request), all or nothing: the
    whole scene is cleared (``clear``: carried objects too), then ``remove``'s ids go,
    ``add``'s objects come, ``detach``'s objects are put down in the world where their
    link holds them, ``attach``'s are taken into their link's frame where they are, and
    the revision goes up by one. The robot's state for attach and detach is
    ``change["state"]`` (all joints 0 without it: the service fills it in, see
    :mod:`arduinobot.service.scene.sync`).

    Raises:
        SceneConflict: ``if_revision`` is not ``state.revision``.
        InvalidRequest: removing an id the scene does not hold (or one twice, or one that
            is carried), a duplicate id, an object the builder refuses, more than
            ``max_objects`` objects, inline meshes of more than ``max_mesh_bytes`` in all
            (``add[i].mesh.data``, before it is parsed), detaching what is not carried, attaching to an unknown
            link or an unknown object, or one that already touches a link that is not a
            touch link (``details.pairs``); each naming its field.
    """
    if "if_revision" in change and change["if_revision"] != state.revision:
        raise SceneConflict(f"the scene is at revision {state.revision}, not "
                            f"{change['if_revision']}: read it and apply again",
                            field="if_revision", current_revision=state.revision)
    cleared = bool(change.get("clear"))
    objects = {} if cleared else {o.id: o for o in state.objects}
    carried = {} if cleared else {a.id: a for a in state.attached}
    clouds = {} if cleared else {c.id: c for c in state.clouds}
    for i, oid in enumerate(change.get("remove") or ()):
        if oid in clouds:
            del clouds[oid]
            continue
        if oid in carried:
            raise InvalidRequest(f"'{oid}' is carried by '{carried[oid].attached.link}': "
                                 "detach it first (in the same apply, if you like)",
                                 field=f"remove[{i}]")
        if oid not in objects:
            raise InvalidRequest(f"no object '{oid}' in the scene"
                                 + (" (cleared first)" if cleared else ""),
                                 field=f"remove[{i}]")
        del objects[oid]
    taken: list[tuple[Mapping[str, Any], str]] = []
    for i, item in enumerate(change.get("add") or ()):
        where = f"add[{i}]"
        oid = item.get("id") if isinstance(item, Mapping) else None
        if isinstance(item, Mapping) and item.get("shape") == "points":
            if oid in objects or oid in carried:
                raise InvalidRequest(f"'{oid}' is an object of the scene, not a cloud",
                                     field=f"{where}.id")
            clouds.pop(str(oid), None)  # a later cloud of the same id replaces it
            taken.append((item, where))
            continue
        if oid in clouds:
            raise InvalidRequest(f"'{oid}' is a point cloud of the scene (remove it in "
                                 "the same apply to replace it)", field=f"{where}.id")
        if oid in objects or oid in carried:
            raise InvalidRequest(f"duplicate id '{oid}': the scene already holds it (remove "
                                 "it in the same apply to replace it)", field=f"{where}.id")
        _check_mesh_bytes(item, where, (*objects.values(), *carried.values()),
                          max_mesh_bytes)  # before the parse it bounds
        obj = builder.build(item, where)
        objects[obj.id] = obj
    if change.get("attach") or change.get("detach"):
        _carry(change, objects, carried, builder)
        total_mesh = sum(inline_mesh_bytes(o.data) for o in objects.values()) \
            + sum(inline_mesh_bytes(a.data) for a in carried.values())
        if total_mesh > max_mesh_bytes:  # a new object attached with its mesh
            raise InvalidRequest(f"the scene's inline meshes would take {total_mesh} bytes, more "
                                 f"than its cap of {max_mesh_bytes}", field="attach",
                                 details={"limit": max_mesh_bytes,
                                          "cap": "MAX_SCENE_MESH_BYTES"})
    for item, where in taken:  # after the carrying: what the robot holds is filtered too
        c = builder.build_cloud({k: v for k, v in item.items() if k != "state"}, where,
                                item.get("state", change.get("state")),
                                objects=objects.values(), carried=carried.values())
        clouds[c.id] = c
    total = len(objects) + len(carried) + len(clouds)
    if total > max_objects:
        raise InvalidRequest(f"the scene would hold {total} objects, "
                             f"more than its cap of {max_objects}", field="add",
                             details={"limit": max_objects, "cap": "MAX_SCENE_OBJECTS"})
    return SceneState(state.revision + 1, tuple(objects.values()), tuple(carried.values()),
                      tuple(clouds.values()))


def inline_mesh_bytes(data: Mapping[str, Any]) -> int:
    """The decoded size [bytes] of an object's inline mesh (0 without one), from its
    base64 text's length: nothing decoded. A carried object's is its ``object``'s."""
    inner = data.get("object")
    if isinstance(inner, Mapping):
        return inline_mesh_bytes(inner)
    mesh = data.get("mesh")
    text = mesh.get("data") if isinstance(mesh, Mapping) else None
    if not isinstance(text, str):
        return 0
    return len(text) * 3 // 4 - text[-2:].count("=")


def _check_mesh_bytes(item: Any, where: str, kept: Iterable[SceneObject | SceneAttached],
                      cap: int) -> None:
    """Refuse ``item`` if its inline mesh takes the scene's (``kept``) over ``cap``."""
    if not isinstance(item, Mapping):
        return
    size = inline_mesh_bytes(item)
    if not size:
        return
    held = sum(inline_mesh_bytes(o.data) for o in kept)
    if held + size > cap:
        raise InvalidRequest(
            f"a mesh of {size} bytes would take the scene's inline meshes to "
            f"{held + size} bytes, more than its cap of {cap} (remove or clear meshes in "
            "the same apply, or give smaller ones)", field=f"{where}.mesh.data",
            details={"limit": cap, "cap": "MAX_SCENE_MESH_BYTES", "scene_bytes": held,
                     "size": size})


def _carry(change: Mapping[str, Any], objects: dict[str, SceneObject],
           carried: dict[str, SceneAttached], builder: SceneBuilder) -> None:
    """``change``'s detach, then attach, on ``objects`` and ``carried`` (in place)."""
    robot = builder.robot
    if robot is None:
        raise InvalidRequest("this scene cannot carry objects (no robot model)",
                             field="attach" if change.get("attach") else "detach")
    q = robot.state(change.get("state"), field="state")
    for i, oid in enumerate(change.get("detach") or ()):
        where = f"detach[{i}]"
        held = carried.pop(oid, None)
        if held is None:
            raise InvalidRequest(f"'{oid}' is not carried"
                                 + (" (it is a free object of the scene)"
                                    if oid in objects else ""), field=where,
                                 details={"attached": sorted(carried)})
        world = robot.link_pose(q, held.attached.link) @ held.attached.shape.pose()
        objects[oid] = builder.build(_posed(held.data["object"], world), where)
    for i, item in enumerate(change.get("attach") or ()):
        where = f"attach[{i}]"
        link = item.get("link")
        if link not in builder.link_names:
            raise InvalidRequest(f"'{link}' is not a link of the robot", field=f"{where}.link",
                                 details={"links": sorted(builder.link_names)})
        for t in item.get("touch_links") or ():
            if t not in builder.link_names:
                raise InvalidRequest(f"'{t}' is not a link of the robot",
                                     field=f"{where}.touch_links")
        ref = item.get("object")
        link_pose = robot.link_pose(q, link)
        if isinstance(ref, str):
            if ref in carried:
                raise InvalidRequest(f"'{ref}' is already carried by "
                                     f"'{carried[ref].attached.link}'", field=f"{where}.object")
            if ref not in objects:
                raise InvalidRequest(f"no object '{ref}' in the scene", field=f"{where}.object",
                                     details={"objects": sorted(objects)})
            free = objects.pop(ref)
            world = free.obstacle.pose() if free.link is None \
                else robot.link_pose(q, free.link) @ free.obstacle.pose()
            data = _posed(free.data, np.linalg.inv(link_pose) @ world)
        else:
            oid = ref.get("id") if isinstance(ref, Mapping) else None
            if oid in objects or oid in carried:
                raise InvalidRequest(f"duplicate id '{oid}': the scene already holds it "
                                     "(attach it by its id)", field=f"{where}.object.id")
            frame = ref.get("frame", WORLD)
            if frame not in (WORLD, link):
                raise InvalidRequest(f"a carried object is given in 'world' or in its link's "
                                     f"frame ('{link}'), not '{frame}'",
                                     field=f"{where}.object.frame")
            given = {k: v for k, v in ref.items() if k != "frame"}
            built = builder.build(given, f"{where}.object")  # validated as given
            data = given if frame == link else _posed(
                given, np.linalg.inv(link_pose) @ built.obstacle.pose())
        held = _held(data, item, builder, f"{where}.object", q=q)
        warn_if_far(robot, held.attached, q, where=where)
        carried[held.id] = held


def _held(obj: Mapping[str, Any], item: Mapping[str, Any], builder: SceneBuilder,
          where: str, *, q: Any = None) -> SceneAttached:
    """A carried object from its wire object (pose in the link's frame) and the rest of
    its attach item (link, touch_links, mass, com), with its default touch links; with a
    state ``q`` (an attach, not a restore), refused if it touches the robot there
    (:func:`arduinobot.scene.frames.hold`)."""
    built = builder.build(obj, where)
    robot = builder.robot
    assert robot is not None  # only an attach or a restore with a robot gets here
    a = hold(robot, built.obstacle, item["link"], q,
             touch_links=tuple(item.get("touch_links") or ()),
             mass=float(item.get("mass", 0.0)), com=item.get("com"),
             where=where.removesuffix(".object"), check=q is not None)
    data: dict[str, Any] = {"object": dict(obj), "link": a.link,
                            "touch_links": list(a.touch_links), "mass": a.mass}
    if a.com is not None:
        data["com"] = list(a.com)
    return SceneAttached(a.id, data, a)


def _posed(data: Mapping[str, Any], pose: np.ndarray) -> dict[str, Any]:
    """``data`` (a wire object) at ``pose`` (4x4), rounded to 1e-12 so a value that is 0
    reads 0; no ``frame`` (the caller knows which it is) nor the ``touch_links`` of an
    object fixed in a link's frame (an attach names its own)."""
    out = {k: v for k, v in data.items() if k not in ("frame", "touch_links")}
    out["xyz"] = [round(float(v), 12) + 0.0 for v in pose[:3, 3]]
    out["rpy"] = [round(v, 12) + 0.0 for v in rpy_of(pose[:3, :3])]
    return out


def restore(data: Mapping[str, Any], builder: SceneBuilder) -> SceneState:
    """A scene from its JSON form (:meth:`SceneState.to_json`: a file, or another
    instance's ``<prefix>/scene`` reply), every object validated again."""
    revision = data.get("revision")
    if isinstance(revision, bool) or not isinstance(revision, int) or revision < 0:
        raise InvalidRequest(f"{revision!r} is not a revision (an integer >= 0)",
                             field="revision")
    objects = data.get("objects") or []
    if not isinstance(objects, list):
        raise InvalidRequest("must be a list of objects", field="objects")
    items = data.get("attached") or []
    if not isinstance(items, list):
        raise InvalidRequest("must be a list of carried objects", field="attached")
    if items and builder.robot is None:
        raise InvalidRequest("this scene cannot carry objects (no robot model)",
                             field="attached")
    if len(objects) > MAX_SCENE_OBJECTS:
        raise InvalidRequest(f"{len(objects)} objects, more than a scene's cap of "
                             f"{MAX_SCENE_OBJECTS}", field="objects")
    free: dict[str, SceneObject] = {}
    taken: list[tuple[Mapping[str, Any], str]] = []
    for i, item in enumerate(objects):
        where = f"objects[{i}]"
        oid = item.get("id") if isinstance(item, Mapping) else None
        if oid in free or any(t.get("id") == oid for t, _ in taken):
            raise InvalidRequest(f"duplicate id '{oid}'", field=f"{where}.id")
        if isinstance(item, Mapping) and item.get("shape") == "points":
            taken.append((item, where))
            continue
        obj = builder.build(item, where)
        free[obj.id] = obj
    ids = set(free)
    held = []
    for i, item in enumerate(items):
        where = f"attached[{i}]"
        if not isinstance(item, Mapping) or not isinstance(item.get("object"), Mapping) \
                or item.get("link") not in builder.link_names:
            raise InvalidRequest("must be {object, link (of the robot), ...}", field=where)
        a = _held(item["object"], item, builder, f"{where}.object")
        if a.id in ids:
            raise InvalidRequest(f"duplicate id '{a.id}'", field=f"{where}.object.id")
        ids.add(a.id)
        held.append(a)
    if len(free) + len(held) > MAX_SCENE_OBJECTS:
        raise InvalidRequest(f"{len(free) + len(held)} objects, more than a scene's cap of "
                             f"{MAX_SCENE_OBJECTS}", field="attached")
    # each cloud kept again at the state it was taken (the objects now filter it)
    clouds = tuple(builder.build_cloud({k: v for k, v in item.items() if k != "state"},
                                       where, item.get("state"), objects=free.values(),
                                       carried=held) for item, where in taken)
    return SceneState(revision, tuple(free.values()), tuple(held), clouds)
