"""`arduinobot scene`: the planning scene the service keeps (every plan and check-state
through the service uses it, plus the request's own --obstacle)."""

from __future__ import annotations

import argparse
import base64
import json
from pathlib import Path
from typing import Any

from .argtypes import UsageError, json_object, numbers, obstacle
from .common import EXIT_OK, add_connection_args, client, wrote

_POSE_HELP = "X,Y,Z or X,Y,Z,ROLL,PITCH,YAW in the world frame [m, rad] (default 0)"
_MESH_FORMATS = {".stl": "stl", ".obj": "obj"}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "scene", help="show or change the planning scene the service keeps",
        description="The service keeps one planning scene per prefix, shared by every "
        "instance and kept on disk: every plan and check-state through the service "
        "avoids its objects (and the request's own --obstacle). Each change is applied "
        "whole or not at all and makes a new revision; --if-revision N applies it only if "
        "the scene is still at revision N (else SCENE_CONFLICT naming the current one).",
        epilog="examples:\n"
        "  arduinobot scene add box:table:1,1,0.1@0,1,0.5\n"
        "  arduinobot scene add-mesh bin bin.stl --pose 0.3,0.8,0.6 --scale 0.001\n"
        "  arduinobot scene show\n"
        "  arduinobot scene save cell.json && arduinobot scene load cell.json\n"
        "  arduinobot plan --local --scene cell.json --named home   # a saved scene, no "
        "service")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)

    def action(name: str, help_: str) -> argparse.ArgumentParser:
        a = actions.add_parser(name, help=help_, description=help_)
        g = a.add_argument_group("service")
        add_connection_args(g, timeout_help="seconds to wait for the reply (default 60)",
                            local_help=argparse.SUPPRESS)
        a.set_defaults(func=cmd_scene, command_parser=a)
        return a

    a = action("show", "print the scene: its revision and objects")
    a.add_argument("--json", action="store_true", help="print the whole scene as JSON")
    a = action("add", "add primitive objects")
    a.add_argument("spec", nargs="+", type=obstacle, metavar="SPEC",
                   help="box:ID:sx,sy,sz@x,y,z[@r,p,y], sphere:ID:r@..., "
                   "cylinder:ID:r,l@... (as plan --obstacle)")
    _if_revision(a)
    a = action("add-mesh", "add a mesh object (binary or ASCII STL, or OBJ; at most 2 MiB, "
               "200000 triangles, 100 m across)")
    a.add_argument("id", metavar="ID")
    a.add_argument("mesh_file", metavar="FILE", help="a .stl or .obj file")
    a.add_argument("--pose", type=numbers_pose, default=[0.0, 0.0, 0.0], metavar="POSE",
                   help=_POSE_HELP)
    a.add_argument("--scale", type=numbers_scale, metavar="S",
                   help="mesh units -> m: one factor or SX,SY,SZ (e.g. 0.001 for mm)")
    _if_revision(a)
    a = action("remove", "remove objects by id")
    a.add_argument("ids", nargs="+", metavar="ID")
    _if_revision(a)
    a = action("clear", "remove every object")
    _if_revision(a)
    a = action("load", "replace the scene by one saved with `scene save`")
    a.add_argument("file", metavar="FILE.json", type=json_object)
    _if_revision(a)
    a = action("save", "write the scene to a file (`scene load` and `plan --local --scene` "
               "read it)")
    a.add_argument("file", metavar="FILE.json")


def add_scene_arg(p: argparse.ArgumentParser) -> None:
    """--scene FILE.json: with --local, the saved scene (`arduinobot scene save`) to
    plan or check against."""
    p.add_argument("--scene", metavar="FILE.json", help="with --local: plan against this "
                   "saved scene (`arduinobot scene save`); the service uses its own")


def _if_revision(a: argparse.ArgumentParser) -> None:
    a.add_argument("--if-revision", type=int, metavar="N",
                   help="apply only if the scene is at revision N")


def numbers_pose(text: str) -> list[float]:
    values = numbers(6)(text) if text.count(",") == 5 else numbers(3)(text)
    return values


def numbers_scale(text: str) -> float | list[float]:
    return numbers(3)(text) if "," in text else numbers(1)(text)[0]


def mesh_object(oid: str, path: str, pose: list[float], scale: float | list[float] | None
                ) -> dict[str, Any]:
    """The scene object of a mesh file (its bytes in base64)."""
    fmt = _MESH_FORMATS.get(Path(path).suffix.lower())
    if fmt is None:
        raise UsageError(f"{path}: a mesh must be a .stl or .obj file")
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise UsageError(f"cannot read {path}: {e.strerror}") from None
    o: dict[str, Any] = {"id": oid, "shape": "mesh",
                         "mesh": {"format": fmt, "data": base64.b64encode(data).decode()},
                         "xyz": pose[:3]}
    if len(pose) == 6:
        o["rpy"] = pose[3:]
    if scale is not None:
        o["scale"] = scale
    return o


def change_of(ns: argparse.Namespace) -> dict[str, Any]:
    """The apply request an action stands for."""
    a = ns.action
    if a == "add":
        change: dict[str, Any] = {"add": ns.spec}
    elif a == "add-mesh":
        change = {"add": [mesh_object(ns.id, ns.mesh_file, ns.pose, ns.scale)]}
    elif a == "remove":
        change = {"remove": ns.ids}
    elif a == "clear":
        change = {"clear": True}
    else:  # load
        objects = ns.file.get("objects")
        if not isinstance(objects, list):
            raise UsageError("the file holds no scene (a JSON object with an 'objects' "
                             "list, as `arduinobot scene save` writes)")
        change = {"clear": True, "add": objects}
    if ns.if_revision is not None:
        change["if_revision"] = ns.if_revision
    return change


def cmd_scene(ns: argparse.Namespace) -> int:
    if ns.local:
        raise UsageError("the scene is the service's; `plan --local --scene FILE.json` "
                         "plans against a saved one")
    with client(ns) as c:
        if ns.action in ("show", "save"):
            scene = c.request("scene")
            if ns.action == "save":
                Path(ns.file).write_text(json.dumps(scene, indent=1) + "\n", "utf-8")
                wrote(ns.file, f"revision {scene['revision']}, "
                      f"{len(scene['objects'])} objects")
            elif ns.json:
                print(json.dumps(scene, indent=1))
            else:
                _print(scene)
            return EXIT_OK
        reply = c.request("scene/apply", change_of(ns))
    print(f"scene at revision {reply['revision']} ({reply.get('objects', '?')} objects)")
    return EXIT_OK


def _print(scene: dict[str, Any]) -> None:
    objects = scene.get("objects", [])
    print(f"scene revision {scene['revision']}: {len(objects)} object(s)")
    for o in objects:
        if o["shape"] == "box":
            dims = "size " + ",".join(f"{v:g}" for v in o["size"])
        elif o["shape"] == "sphere":
            dims = f"radius {o['radius']:g}"
        elif o["shape"] == "cylinder":
            dims = f"radius {o['radius']:g} length {o['length']:g}"
        else:
            size = len(base64.b64decode(o["mesh"]["data"]))
            dims = f"{o['mesh']['format']} mesh, {size} bytes, scale {o.get('scale', 1)}"
        xyz = ",".join(f"{v:g}" for v in o.get("xyz", (0, 0, 0)))
        print(f"  {o['id']:<20} {o['shape']:<8} {dims}  @ {xyz}")
