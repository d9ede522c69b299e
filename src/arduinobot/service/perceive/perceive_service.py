"""The ``<prefix>/perceive`` queryable (``perceive_request.json``, answered
``perceive_response.json``).

The image is the request's PNG/JPEG, or with ``"image": "topic"`` the latest of the
service's camera topic (``serve --ros2 --camera-topic``: an ``ImageSource``). The camera
is the request's link, else (a topic's image) the link the image's frame_id names, else
the model's Gazebo camera sensor's; its intrinsics the request's, else the topic's
CameraInfo, else that sensor's (an ideal pinhole); the marker map the
request's, else ``objects.yaml`` beside the robot's ``tasks.yaml``. With ``apply``, the
seen objects (padded by their uncertainty) go into the kept scene through
``<prefix>/scene/apply`` like any client's change: one apply, at the revision read, that
removes the objects of the same ids and adds the new ones, so nothing of the scene
changes when any of it is refused.
"""

from __future__ import annotations

import base64
import binascii
import logging
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import orjson
import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest, PlanningError
from arduinobot.description import Description, read_model_text
from arduinobot.scene.state import SceneSnapshot
from arduinobot.service.extension import Host
from arduinobot.service.process.worker import DescriptionSpec
from arduinobot.service.queries import guarded

if TYPE_CHECKING:
    from arduinobot.perception.raw_image import CapturedImage

_log = logging.getLogger(__name__)

#: The latest image of a camera topic (raises ImageInvalid when there is none).
ImageSource = Callable[[], "CapturedImage"]

#: Largest perceive payload [bytes]: a full-resolution PNG of the course's camera
#: (2304 x 1296) in base64, with room.
MAX_PERCEIVE_PAYLOAD = 16 * 2**20
#: How long the scene apply of a perceive may take [s].
APPLY_TIMEOUT = 10.0
#: Applies tried when the scene moves on between reading it and applying.
APPLY_ATTEMPTS = 3


class SceneApplyFailed(PlanningError):
    """The kept scene refused the seen objects (its code and details are relayed)."""

    def __init__(self, code: str, message: str, details: Mapping[str, Any]) -> None:
        self.code = Code(code) if code in Code.__members__ else Code.INTERNAL
        super().__init__(f"scene apply: {message}", details=details)


def decode_perceive(payload: bytes) -> dict[str, Any]:
    """A perceive request: at most :data:`MAX_PERCEIVE_PAYLOAD` bytes of strict JSON,
    valid against ``perceive_request.json``.

    Raises:
        InvalidRequest: naming the field.
    """
    # the image is one long string: no element or string caps, the size cap bounds it
    return wire.validate("perceive", wire.parse_json(payload, limit=MAX_PERCEIVE_PAYLOAD))


class PerceiveService:
    """``<prefix>/perceive``: see :mod:`arduinobot.service.perceive`."""

    def __init__(self, session: zenoh.Session, prefix: str, description: Description, *,
                 spec: DescriptionSpec, scene: Callable[[], SceneSnapshot | None],
                 camera: ImageSource | None = None) -> None:
        self.session, self.prefix, self.description = session, prefix, description
        self.spec, self.scene, self.camera = spec, scene, camera
        self._sensors: tuple[Any, ...] | None = None
        self._entities: list[zenoh.Queryable] = []

    def start(self) -> None:
        key = f"{self.prefix}/perceive"

        def handle(query: zenoh.Query) -> None:
            raw = query.payload.to_bytes() if query.payload is not None else b""
            query.reply(key, wire.encode(self.perceive(decode_perceive(raw))),
                        encoding=wire.JSON)

        # exact: a wildcard must not change the scene; threaded: it waits for the scene
        on_query = guarded(key, handle, exact=True, threaded=True, drop=True,
                           internal="unexpected failure in the perceive service")
        self._entities.append(self.session.declare_queryable(key, on_query, complete=True))
        _log.info("perceive: key %s", key)

    def close(self) -> None:
        for e in self._entities:
            try:
                e.undeclare()
            except zenoh.ZError as err:  # the session's end drops it too
                _log.debug("perceive: undeclare: %s", err)
        self._entities.clear()

    # --- the request ----------------------------------------------------------------

    def sensors(self) -> tuple[Any, ...]:
        """The model's Gazebo camera sensors (read once, from the model's URDF)."""
        if self._sensors is None:
            from arduinobot.perception.intrinsics import camera_sensors
            text, _ = read_model_text(self.spec.path, args=dict(self.spec.args) or None,
                                      packages=self.description.packages)
            self._sensors = camera_sensors(text)
        return self._sensors

    def perceive(self, body: Mapping[str, Any]) -> dict[str, Any]:
        """The reply to a valid request (see the module doc)."""
        try:
            import cv2  # noqa: F401 -- the see extra: refused clearly without it
        except ImportError:
            raise InvalidRequest("this service cannot see: install the 'see' extra "
                                 "(opencv-python-headless)", field="image") from None
        from arduinobot.description.model import rpy_of as rpy_of_matrix
        from arduinobot.perception.camera import default_camera
        from arduinobot.perception.errors import ImageInvalid
        from arduinobot.perception.intrinsics import Intrinsics
        from arduinobot.perception.locate import perceive

        sensors = self.sensors()
        captured = self.captured() if body["image"] == "topic" else None
        camera = body.get("camera")
        if not camera and captured is not None:
            if captured.frame_id not in self.description.robot.links:
                raise InvalidRequest(f"the image from {captured.topic} is in frame "
                                     f"{captured.frame_id!r}, which is not a link of the "
                                     "model: name the camera's link", field="camera")
            camera = captured.frame_id
        camera = camera or default_camera(self.description, tuple(s.link for s in sensors))
        if "intrinsics" in body:
            intr = Intrinsics.from_mapping(body["intrinsics"])
        elif captured is not None and captured.intrinsics is not None:
            intr = captured.intrinsics
        else:
            found = [s for s in sensors if s.link == camera]
            if not found:
                if camera not in self.description.robot.links:
                    raise InvalidRequest(f"{camera!r} is not a link of the model",
                                         field="camera")
                raise InvalidRequest(f"the model has no Gazebo camera sensor on {camera!r}: "
                                     "give the camera's intrinsics", field="intrinsics")
            intr = found[0].intrinsics()
        markers = self.marker_map(body.get("markers"))
        image: Any
        if captured is not None:
            image, image_format = captured.gray, None
        else:
            try:
                image = base64.b64decode(body["image"]["data"], validate=True)
            except (binascii.Error, ValueError):
                raise ImageInvalid("is not base64", field="image.data") from None
            image_format = body["image"]["format"]
        seen = perceive(image, description=self.description, markers=markers, camera=camera,
                        intrinsics=intr, state=body.get("state"), image_format=image_format)
        cam = seen.camera
        reply: dict[str, Any] = {
            "detections": [d.to_dict() for d in seen.detections],
            "camera": {"link": cam.link, "frame": cam.frame, "optical": cam.optical,
                       "xyz": [float(x) for x in cam.pose[:3, 3]],
                       "rpy": list(rpy_of_matrix(cam.pose[:3, :3]))},
            "intrinsics": intr.to_dict()}
        if captured is not None:
            reply["image"] = captured.describe()
        if body.get("apply"):
            unseen = ([o.id for o in markers.objects.values()
                       if o.id not in {d.marked.id for d in seen.detections}]
                      if body.get("remove_unseen") else [])
            revision, removed = self.apply([d.obstacle() for d in seen.detections], unseen)
            reply["revision"], reply["removed"] = revision, removed
        return reply

    def captured(self) -> CapturedImage:
        """The camera topic's latest image.

        Raises:
            InvalidRequest: the service has no camera topic; ImageInvalid: no image yet,
                or an unreadable one.
        """
        if self.camera is None:
            raise InvalidRequest("this service has no camera topic: start it with `serve "
                                 "--ros2 --camera-topic TOPIC`, or send the image",
                                 field="image")
        return self.camera()

    def marker_map(self, given: Any) -> Any:
        """The request's marker map, else ``objects.yaml`` beside the robot's tasks.yaml."""
        from arduinobot.perception.markers import MarkerMap, load_marker_map
        if given is not None:
            return MarkerMap.from_mapping(given)
        tasks = self.description.config.tasks
        path = Path(tasks).parent / "objects.yaml" if tasks is not None else None
        if path is None or not path.is_file():
            raise InvalidRequest("no marker map: give markers, or put objects.yaml beside "
                                 "the robot's tasks.yaml", field="markers")
        return load_marker_map(path.read_text("utf-8"))

    def apply(self, obstacles: list[Any], unseen: list[str]) -> tuple[int, list[str]]:
        """Put ``obstacles`` into the kept scene (replacing same ids) and take ``unseen``
        out: one apply at the revision read; retried if the scene moved on meanwhile.
        The new revision, and the ids removed as unseen."""
        failure = SceneApplyFailed(Code.BUSY, "the kept scene did not answer", {})
        turn = "ask"  # the next turn if this loses a race (arduinobot.service.scene.turns)
        for _ in range(APPLY_ATTEMPTS):
            snap = self.scene()
            held = {o.id for o in snap.obstacles} if snap is not None else set()
            gone = [i for i in unseen if i in held]
            change: dict[str, Any] = {
                "remove": sorted({o.id for o in obstacles if o.id in held} | set(gone)),
                "add": [{"id": o.id, "shape": o.shape, "xyz": list(o.xyz), "rpy": list(o.rpy),
                         **({"size": list(o.size)} if o.size is not None else {}),
                         **({"radius": o.radius} if o.radius is not None else {}),
                         **({"length": o.length} if o.length is not None else {})}
                        for o in obstacles]}
            if snap is not None:
                change["if_revision"] = snap.revision
                change["turn"] = turn
            replies = list(self.session.get(f"{self.prefix}/scene/apply",
                                            payload=wire.encode(change), timeout=APPLY_TIMEOUT))
            for r in replies:
                if r.ok is not None:
                    return int(orjson.loads(r.ok.payload.to_bytes())["revision"]), gone
                err = orjson.loads(r.err.payload.to_bytes()).get("error", {})
                failure = SceneApplyFailed(str(err.get("code", Code.INTERNAL)),
                                           str(err.get("message", "")),
                                           err.get("details") or {})
                break
            else:
                failure = SceneApplyFailed(Code.BUSY, "the kept scene did not answer", {})
            if failure.code != Code.SCENE_CONFLICT:
                break
            turn = failure.details.get("turn") or "ask"
            time.sleep(0.2)  # this instance's copy of the scene catches up
        raise failure


def perceive_extension(*, spec: DescriptionSpec, camera: ImageSource | None = None
                       ) -> Callable[[Host], PerceiveService]:
    """An extension (:mod:`arduinobot.service.extension`) serving ``<prefix>/perceive``
    for the robot ``spec`` loads, applying what it sees to the host's kept scene;
    ``camera``: the latest image of a camera topic (``"image": "topic"``)."""
    def make(host: Host) -> PerceiveService:
        svc = PerceiveService(host.session, host.prefix, host.description, spec=spec,
                              scene=host.scene, camera=camera)
        svc.start()
        return svc
    return make
