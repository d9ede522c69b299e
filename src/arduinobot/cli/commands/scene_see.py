"""`arduinobot scene see IMAGE` (or `--topic`: the service's camera topic): the objects a
camera image shows, through their markers, put into the service's kept scene
(``<prefix>/perceive``, issue 41)."""

from __future__ import annotations

import argparse
import base64
import math
import time
from pathlib import Path
from typing import Any

import yaml

from arduinobot.cli.argtypes import UsageError, file_problem
from arduinobot.cli.common import joints_by_name

_FORMATS = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg"}


def add_arguments(a: argparse.ArgumentParser) -> None:
    a.add_argument("image", metavar="IMAGE", nargs="?",
                   help="a PNG or JPEG from the camera (or --topic)")
    a.add_argument("--topic", action="store_true",
                   help="the latest image of the service's camera topic instead (`serve "
                   "--ros2 --camera-topic TOPIC`; its camera the link its frame_id names, "
                   "its intrinsics the CameraInfo beside it)")
    a.add_argument("--camera", metavar="LINK",
                   help="the camera's link (default: the model's Gazebo camera sensor's)")
    a.add_argument("--intrinsics", metavar="FILE",
                   help="the camera's ROS camera_info YAML (default: from the model's "
                   "Gazebo camera sensor: its resolution and horizontal field of view)")
    a.add_argument("--markers", metavar="FILE",
                   help="objects.yaml: marker ids to objects (default: the service's, beside "
                   "the robot's tasks.yaml)")
    a.add_argument("--state", metavar="JOINTS",
                   help="the robot's state when the image was taken: J1,J2,... or NAME=V,... "
                   "(default: the model's initial positions)")
    a.add_argument("--dry-run", action="store_true",
                   help="only print what is seen: the scene is not changed")
    a.add_argument("--remove-unseen", action="store_true",
                   help="take the map's objects the image does not show out of the scene")


def request_of(ns: argparse.Namespace) -> dict[str, Any]:
    """The perceive request of ``scene see``'s arguments (files read here)."""
    if (ns.image is None) == (not ns.topic):
        raise UsageError("give an IMAGE file or --topic (the service's camera topic), "
                         "one of them")
    body: dict[str, Any] = {"image": "topic", "apply": not ns.dry_run}
    if ns.image is not None:
        path = Path(ns.image)
        fmt = _FORMATS.get(path.suffix.lower())
        if fmt is None:
            raise UsageError(f"{ns.image}: give a .png, .jpg or .jpeg image")
        body["image"] = {"format": fmt, "data": base64.b64encode(_read(path)).decode()}
    if ns.remove_unseen:
        body["remove_unseen"] = True
    if ns.camera:
        body["camera"] = ns.camera
    if ns.intrinsics:
        from arduinobot.perception.intrinsics import from_camera_info
        intr = from_camera_info(_read(Path(ns.intrinsics)).decode("utf-8"))
        body["intrinsics"] = {"fx": intr.fx, "fy": intr.fy, "cx": intr.cx, "cy": intr.cy,
                              **({"width": intr.width, "height": intr.height}
                                 if intr.width else {}),
                              **({"distortion": list(intr.distortion)}
                                 if intr.distortion else {})}
    if ns.markers:
        doc = yaml.safe_load(_read(Path(ns.markers)).decode("utf-8"))
        body["markers"] = doc["markers"] if isinstance(doc, dict) and "markers" in doc else doc
        objs = body["markers"].get("objects") if isinstance(body["markers"], dict) else None
        if isinstance(objs, dict):  # YAML's integer keys: JSON's are strings
            body["markers"]["objects"] = {str(k): v for k, v in objs.items()}
    return body


def run(ns: argparse.Namespace, c: Any, body: dict[str, Any]) -> dict[str, Any]:
    """Send ``scene see``'s request ``body`` (:func:`request_of`) through client ``c`` and
    print what was seen."""
    if ns.state:
        body["state"] = joints_by_name(c.request("description"), ns.state, group="all",
                                       flag="--state")
    reply: dict[str, Any] = c.request("perceive", body)
    cam = reply["camera"]
    if "image" in reply:  # a topic's: which image, from when
        img = reply["image"]
        print(f"image from {img['topic']}: {img['width']} x {img['height']} {img['encoding']}, "
              f"frame {img['frame_id']}, {time.time() - img['stamp']:.1f} s old"
              + ("" if img["camera_info"] else " (no calibration on camera_info)"))
    print(f"camera {cam['link']} at ({', '.join(f'{x:.3f}' for x in cam['xyz'])}) m")
    for d in reply["detections"]:
        rpy = ", ".join(f"{math.degrees(x):.1f}" for x in d["rpy"])
        print(f"  marker {d['marker']} -> {d['object']} at "
              f"({', '.join(f'{x:.3f}' for x in d['xyz'])}) m, rpy ({rpy}) deg; "
              f"reprojection {d['reprojection_error']:.2f} px, "
              f"+-{1e3 * d['uncertainty']:.1f} mm (padding)")
    if "revision" in reply:
        gone = f", removed unseen {', '.join(reply['removed'])}" if reply.get("removed") else ""
        print(f"scene at revision {reply['revision']}{gone}")
    return reply


def _read(path: Path) -> bytes:
    """A file named on the command line, or a one-line refusal naming it."""
    try:
        return path.read_bytes()
    except OSError as e:
        raise file_problem(path, e) from None
