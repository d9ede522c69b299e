"""`arduinobot task FILE --sim` with a ``see`` section: see and pick on the twin, closed
loop (issue 41). The twin's camera renders the objects where they really are
(``see.twin``), perception finds them through their markers, and the task is planned
against what was seen (padded by its uncertainty), never against the truth; the twin
then runs it with each picked object a free body where it really is.

The section::

    see:
      camera: rgb_camera_link          # default: the model's Gazebo camera sensor's link
      markers: {dictionary: 4x4_50, size: 0.06, objects: {3: {id: box, ...}}}
      twin:                            # where the objects really are (the twin's world)
        box: {xyz: [0.8, 0.47, 0.29], rpy: [0, 0, 0.2]}
      lights: 1                        # 1: overhead, 2: a dim side spot
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.cli.argtypes import UsageError
from arduinobot.description import Description, read_model_text
from arduinobot.scene.obstacles import Obstacle
from arduinobot.scene.shapes import kinds, shape_class

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Seen:
    """What the twin's camera showed: the obstacles as seen (padded, for planning), the
    objects as they really are (for the twin), and the wire's detections."""

    obstacles: tuple[Obstacle, ...]
    truth: Mapping[str, Obstacle]
    detections: tuple[dict[str, Any], ...]


def see_on_twin(section: Any, desc: Description, *, model: str | None,
                args: Mapping[str, str], obstacles: Any = ()) -> Seen:
    """Render the ``see`` section's twin among the task's ``obstacles`` (their JSON form:
    they can hide a marker), detect its markers and place what they show."""
    from arduinobot.perception.camera import camera_frame, default_camera
    from arduinobot.perception.image import encode
    from arduinobot.perception.intrinsics import camera_sensors
    from arduinobot.perception.locate import perceive
    from arduinobot.perception.markers import MarkerMap
    from arduinobot.perception.twin_view import Light, render

    if not isinstance(section, Mapping):
        raise UsageError("see: must be a mapping (camera, markers, twin)")
    markers = MarkerMap.from_mapping(section.get("markers"), where="see.markers")
    twin = section.get("twin")
    if not isinstance(twin, Mapping) or not twin:
        raise UsageError("see.twin: where the objects are in the twin ({id: {xyz, rpy}})")
    by_id = {o.id: o for o in markers.objects.values()}
    poses: dict[str, np.ndarray] = {}
    truth: dict[str, Obstacle] = {}
    for oid, pose in twin.items():
        if oid not in by_id:
            raise UsageError(f"see.twin.{oid}: not an object of see.markers")
        o = by_id[oid]
        obst = Obstacle(oid, o.geometry, xyz=tuple(pose.get("xyz", (0, 0, 0))),
                        rpy=tuple(pose.get("rpy", (0, 0, 0))), where=f"see.twin.{oid}")
        truth[oid], poses[oid] = obst, obst.pose()
    sensors = camera_sensors(read_model_text(model, args=dict(args) or None,
                                             packages=desc.packages)[0])
    link = section.get("camera") or default_camera(desc, tuple(s.link for s in sensors))
    found = [s for s in sensors if s.link == link]
    if not found:
        raise UsageError(f"see.camera: the model has no Gazebo camera sensor on {link!r}")
    intr = found[0].intrinsics()
    lights = {1: (Light(direction=(0.2, 0.1, -1.0), diffuse=0.8, ambient=0.25),),
              2: (Light(directional=False, position=(0.2, -0.8, 1.2),
                        direction=(0.5, 1.0, -1.0), diffuse=0.45, ambient=0.1),)}
    # the twin's camera draws shapes given by their dimensions, not a file's (a mesh)
    files = tuple(k for k in kinds() if not shape_class(k).portable)
    others = [Obstacle.from_mapping(o, where=f"obstacles[{i}]")
              for i, o in enumerate(obstacles or ()) if isinstance(o, Mapping)
              and o.get("id") not in truth and o.get("shape") not in files]
    rgb = render(markers, poses, camera_frame(desc, link), intr,
                 lights=lights[int(section.get("lights", 1))], obstacles=others)
    seen = perceive(encode(rgb), description=desc, markers=markers, camera=link,
                    intrinsics=intr)
    for d in seen.detections:
        err = float(np.linalg.norm(d.pose[:3, 3] - poses[d.marked.id][:3, 3]))
        print(f"saw {d.marked.id} (marker {d.marker}) {1e3 * err:.1f} mm from where it is, "
              f"padded {1e3 * d.uncertainty:.1f} mm")
    return Seen(obstacles=tuple(d.obstacle() for d in seen.detections), truth=truth,
                detections=tuple(d.to_dict() for d in seen.detections))


def picked(body: Mapping[str, Any]) -> set[str]:
    """The ids a task body's ``attach`` steps take."""
    steps = body.get("steps") or []
    return {s["attach"] for s in steps if isinstance(s, Mapping)
            and isinstance(s.get("attach"), str)}


def with_seen(body: dict[str, Any], seen: Seen) -> dict[str, Any]:
    """The task ``body`` with the seen objects in its scene (replacing same ids): padded
    by their uncertainty, but for those the task picks up, planned at their nominal size
    where they were seen: a padded held object would sink into what it rests on (a box
    2 mm above its table, padded 5 mm) and every lift would start in collision."""
    ids = {o.id for o in seen.obstacles}
    held = picked(body)
    kept = [o for o in body.get("obstacles", []) if not (isinstance(o, Mapping)
                                                        and o.get("id") in ids)]
    nominal = {d["object"]: d for d in seen.detections}
    obstacles = [o if o.id not in held else _unpadded(o, nominal[o.id]["uncertainty"])
                 for o in seen.obstacles]
    added = [{"id": o.id, "shape": o.shape, "xyz": list(o.xyz), "rpy": list(o.rpy),
              **({"size": list(o.size)} if o.size is not None else {}),
              **({"radius": o.radius} if o.radius is not None else {}),
              **({"length": o.length} if o.length is not None else {})}
             for o in obstacles]
    return {**body, "obstacles": [*kept, *added]}


def _unpadded(o: Obstacle, pad: float) -> Obstacle:
    """``o`` without the padding ``pad`` [m] its detection put on it."""
    return Obstacle(o.id, o.geometry.grown(-pad), xyz=o.xyz, rpy=o.rpy)
