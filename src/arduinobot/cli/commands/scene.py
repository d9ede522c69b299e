"""`arduinobot scene`: the planning scene the service keeps (every plan and check-state
through the service uses it, plus the request's own --obstacle)."""

from __future__ import annotations

import argparse
import base64
import json
from pathlib import Path
from typing import Any

from arduinobot.cli.argtypes import (
    FileProblem,
    UsageError,
    file_problem,
    joint_values,
    json_object,
    numbers,
    obstacle,
)
from arduinobot.cli.commands import scene_see
from arduinobot.cli.common import EXIT_OK, add_connection_args, client, joints_by_name, wrote
from arduinobot.scene.mesh_codec import stl_problem
from arduinobot.scene.shapes import shape_class

_POSE_HELP = ("X,Y,Z or X,Y,Z,ROLL,PITCH,YAW in the world frame (or --frame's) [m, rad] "
              "(default 0)")
_MESH_FORMATS = {".stl": "stl", ".obj": "obj"}
_STATE_HELP = ("the robot's state where it takes or puts down the object: J1,J2,... in "
               "the robot's joint order, or NAME=V,...; missing joints 0 (default: the "
               "executing robot's state if the service has one, else all joints 0)")


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
        "  arduinobot scene add box:cam:0.05,0.05,0.05@0,0.2,0.3 --frame claw_support\n"
        "  arduinobot scene add-mesh bin bin.stl --pose 0.3,0.8,0.6 --scale 0.001\n"
        "  arduinobot scene add-cloud camera scan.ply --resolution 0.01 --frame base_link\n"
        "  arduinobot scene attach cup --link claw_support --mass 0.2 --state 0.3,0.5\n"
        "  arduinobot scene detach cup --state -0.4,0.5\n"
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
    _frame_args(a)
    _if_revision(a)
    a = action("add-mesh", "add a mesh object (binary or ASCII STL, or OBJ; at most 2 MiB, "
               "200000 triangles, 100 m across)")
    a.add_argument("id", metavar="ID")
    a.add_argument("mesh_file", metavar="FILE", help="a .stl or .obj file")
    a.add_argument("--pose", type=numbers_pose, default=[0.0, 0.0, 0.0], metavar="POSE",
                   help=_POSE_HELP)
    a.add_argument("--scale", type=numbers_scale, metavar="S",
                   help="mesh units -> m: one factor or SX,SY,SZ (e.g. 0.001 for mm)")
    _frame_args(a)
    _if_revision(a)
    a = action("add-cloud", "add a point cloud (.ply, .pcd, .xyz/.csv) as occupied cells: "
               "less the robot's own at --state and the scene's objects; a cloud of the "
               "same id is replaced")
    a.add_argument("id", metavar="ID")
    a.add_argument("cloud_file", metavar="FILE", help="a .ply, .pcd, .xyz, .csv or .txt "
                   "file of x, y, z points [m]")
    a.add_argument("--resolution", type=float, default=0.01, metavar="M",
                   help="the cells' edge [m], 0.002 to 0.1 (default 0.01)")
    a.add_argument("--frame", metavar="LINK", help="the points are in this link's frame "
                   "(a camera on the arm), placed where it is at --state; default: the world")
    a.add_argument("--pose", type=numbers_pose, metavar="POSE",
                   help="the points' frame in --frame's: " + _POSE_HELP)
    a.add_argument("--padding", type=float, metavar="M",
                   help="cells this near the robot are its own [m] (default 0.01)")
    a.add_argument("--unknown", choices=("free", "occupied"), default="free",
                   help="what the space the camera did not see is: free (default), or "
                   "occupied behind the measured surface (needs --camera)")
    a.add_argument("--camera", type=_json_text, metavar="JSON",
                   help='with --unknown occupied: {"link": L or "xyz"/"rpy", "hfov": rad, '
                   '"vfov": rad, "range": m}')
    a.add_argument("--state", type=joint_values, metavar="Q",
                   help="the robot's state when the cloud was taken: J1,J2,... in the "
                   "robot's joint order, or NAME=V,...; missing joints 0 (default: the "
                   "executing robot's state if the service has one, else all joints 0)")
    _if_revision(a)
    a = action("remove", "remove objects by id")
    a.add_argument("ids", nargs="+", metavar="ID")
    _if_revision(a)
    a = action("attach", "the gripper takes an object of the scene: it is carried in the "
               "link's frame from where it is now (checked with the link in every plan, "
               "its mass in the effort check)")
    a.add_argument("id", metavar="ID", help="an object of the scene")
    a.add_argument("--link", required=True, metavar="L", help="the link that holds it")
    a.add_argument("--mass", type=float, metavar="KG", help="its mass [kg] (default 0)")
    a.add_argument("--com", type=numbers(3), metavar="X,Y,Z",
                   help="its centre of mass in the link's frame [m] (default: its centroid)")
    a.add_argument("--touch", type=_names, metavar="L1,L2",
                   help="links it may touch (default: the end effector's holding it)")
    a.add_argument("--state", type=joint_values, metavar="Q", help=_STATE_HELP)
    _if_revision(a)
    a = action("detach", "put a carried object down: it stays in the scene where the link "
               "holds it")
    a.add_argument("ids", nargs="+", metavar="ID")
    a.add_argument("--state", type=joint_values, metavar="Q", help=_STATE_HELP)
    _if_revision(a)
    a = action("clear", "remove every object (carried ones too)")
    _if_revision(a)
    a = action("load", "replace the scene by one saved with `scene save`")
    a.add_argument("file", metavar="FILE.json", type=json_object)
    _if_revision(a)
    a = action("see", "put what a camera image shows into the scene: the objects its "
               "markers sit on (objects.yaml), placed from the camera's pose")
    scene_see.add_arguments(a)
    a = action("save", "write the scene to a file (`scene load` and `plan --local --scene` "
               "read it)")
    a.add_argument("file", metavar="FILE.json")


def add_scene_arg(p: argparse.ArgumentParser) -> None:
    """--scene FILE.json: with --local, the saved scene (`arduinobot scene save`) to
    plan or check against."""
    p.add_argument("--scene", metavar="FILE.json", help="with --local: plan against this "
                   "saved scene (`arduinobot scene save`); the service uses its own")


def _frame_args(a: argparse.ArgumentParser) -> None:
    a.add_argument("--frame", metavar="LINK", help="give the pose in this link's frame: the "
                   "object is fixed to the link and moves with it (a camera, a tool "
                   "holder); default: the world")
    a.add_argument("--touch-links", type=_names, metavar="L1,L2",
                   help="with --frame: links it may touch besides those rigidly joined to "
                   "LINK (e.g. fingers it sits between)")


def _framed(objects: list[dict[str, Any]], ns: argparse.Namespace) -> list[dict[str, Any]]:
    if ns.touch_links and not ns.frame:
        raise UsageError("--touch-links needs --frame: a world object touches nothing of "
                         "the robot")
    extra: dict[str, Any] = {}
    if ns.frame:
        extra["frame"] = ns.frame
    if ns.touch_links:
        extra["touch_links"] = ns.touch_links
    return [{**o, **extra} for o in objects]


def _if_revision(a: argparse.ArgumentParser) -> None:
    a.add_argument("--if-revision", type=int, metavar="N",
                   help="apply only if the scene is at revision N")


def _names(text: str) -> list[str]:
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise argparse.ArgumentTypeError("give one or more link names: L1,L2")
    return names


def _json_text(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as e:
        raise argparse.ArgumentTypeError(f"not JSON: {e}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError("must be a JSON object")
    return value


def cloud_object(ns: argparse.Namespace) -> dict[str, Any]:
    """The scene object of ``add-cloud``'s file and options (its points as xyz32)."""
    from arduinobot.client.cloud_files import read_cloud_file
    from arduinobot.contract.errors import InvalidRequest
    from arduinobot.scene.cloud import encode_points

    try:
        points = read_cloud_file(ns.cloud_file)
    except InvalidRequest as e:
        raise UsageError(str(e)) from None
    o: dict[str, Any] = {"id": ns.id, "shape": "points", "points": encode_points(points),
                         "resolution": ns.resolution, "unknown": ns.unknown}
    if ns.frame:
        o["frame"] = ns.frame
    if ns.pose is not None:
        o["xyz"] = ns.pose[:3]
        if len(ns.pose) == 6:
            o["rpy"] = ns.pose[3:]
    if ns.padding is not None:
        o["padding"] = ns.padding
    if ns.camera is not None:
        o["camera"] = ns.camera
    elif ns.unknown == "occupied":
        raise UsageError("--unknown occupied needs --camera (where it is and what it sees)")
    return o


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
        raise file_problem(path, e) from None
    problem = stl_problem(data) if fmt == "stl" else None
    if problem is not None:  # here, naming the file: the service can only name the field
        raise FileProblem(f"{path}: {problem}")
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
        change: dict[str, Any] = {"add": _framed(ns.spec, ns)}
    elif a == "add-mesh":
        change = {"add": _framed([mesh_object(ns.id, ns.mesh_file, ns.pose, ns.scale)], ns)}
    elif a == "add-cloud":
        change = {"add": [cloud_object(ns)]}
    elif a == "remove":
        change = {"remove": ns.ids}
    elif a == "clear":
        change = {"clear": True}
    elif a == "attach":
        item: dict[str, Any] = {"object": ns.id, "link": ns.link}
        if ns.touch:
            item["touch_links"] = ns.touch
        if ns.mass is not None:
            item["mass"] = ns.mass
        if ns.com is not None:
            item["com"] = ns.com
        change = {"attach": [item]}
    elif a == "detach":
        change = {"detach": ns.ids}
    else:  # load
        objects = ns.file.get("objects")
        if not isinstance(objects, list):
            raise UsageError("the file holds no scene (a JSON object with an 'objects' "
                             "list, as `arduinobot scene save` writes)")
        change = {"clear": True, "add": objects}
        # carried objects as saved: already in their link's frame
        carried = ns.file.get("attached") or []
        if not isinstance(carried, list) or not all(
                isinstance(c, dict) and isinstance(c.get("object"), dict) for c in carried):
            raise UsageError("the file's 'attached' is not a list of carried objects")
        if carried:
            change["attach"] = [{**c, "object": {**c["object"], "frame": c.get("link")}}
                                for c in carried]
    if ns.if_revision is not None:
        change["if_revision"] = ns.if_revision
    return change


def cmd_scene(ns: argparse.Namespace) -> int:
    if ns.local:
        raise UsageError("the scene is the service's; `plan --local --scene FILE.json` "
                         "plans against a saved one")
    # the files the command names are read before the service is reached: a missing one
    # is said as such, whether or not a service runs
    body = scene_see.request_of(ns) if ns.action == "see" else None
    change = None if ns.action in ("see", "show", "save") else change_of(ns)
    with client(ns) as c:
        if body is not None:
            scene_see.run(ns, c, body)
            return EXIT_OK
        if change is None:  # show or save
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
        if getattr(ns, "state", None):
            change["state"] = joints_by_name(c.request("description"), ns.state, group="all",
                                             flag="--state")
        reply = c.request("scene/apply", change)
    carried = f", {reply['attached']} carried" if reply.get("attached") else ""
    source = {"request": "at --state", "robot": "at the robot's state",
              "zero": "at all joints 0 (no --state, no executing robot)"}.get(
                  reply.get("state_source", ""), "")
    print(f"scene at revision {reply['revision']} ({reply.get('objects', '?')} objects"
          f"{carried})" + (f", {source}" if source else ""))
    for cid, n in (reply.get("clouds") or {}).items():
        print(f"  cloud {cid}: {n['kept']} of {n['points']} points kept in {n['cells']} "
              f"cells ({n['dropped']} not finite, {n['filtered_robot']} on the robot, "
              f"{n['filtered_objects']} in objects); unseen space {n['unknown']}")
    return EXIT_OK


def _print(scene: dict[str, Any]) -> None:
    objects = scene.get("objects", [])
    carried = scene.get("attached", [])
    print(f"scene revision {scene['revision']}: {len(objects)} object(s)"
          + (f", {len(carried)} carried" if carried else ""))
    for o in objects:
        frame = o.get("frame", "world")
        print(f"  {_line(o)}" + ("" if frame == "world" else f" in {frame}'s frame, fixed"))
    for c in carried:
        print(f"  {_line(c['object'])} in {c['link']}'s frame, carried, "
              f"{c.get('mass', 0):g} kg")


def _line(o: dict[str, Any]) -> str:
    if o["shape"] == "points":  # a cloud: not a shape of the registry (its cells are)
        dims = f"cells {o['resolution']:g} m, unseen space {o.get('unknown', 'free')}"
    else:
        dims = shape_class(o["shape"]).summary(o)
    xyz = ",".join(f"{v:g}" for v in o.get("xyz", (0, 0, 0)))
    return f"{o['id']:<20} {o['shape']:<8} {dims}  @ {xyz}"
