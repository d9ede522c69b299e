"""A camera's intrinsics: from a ROS ``camera_info`` YAML, or from the URDF's Gazebo
camera sensor (resolution and horizontal field of view, an ideal pinhole) when the
camera has no calibration.

Pixel coordinates are OpenCV's: pixel (0, 0)'s centre is the origin, so an ideal camera's
optical axis meets the image at ((width - 1) / 2, (height - 1) / 2).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import yaml

from arduinobot.contract.errors import InvalidRequest


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera.

    Attributes:
        fx, fy: focal lengths [px]; cx, cy: principal point [px].
        width, height: image size [px] (0: unknown, not checked against the image).
        distortion: OpenCV's coefficients (k1, k2, p1, p2[, k3, ...]); () for none.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int = 0
    height: int = 0
    distortion: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "cx", "cy"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InvalidRequest(f"{v!r} is not a finite number [px]",
                                     field=f"intrinsics.{name}")
        if self.fx <= 0 or self.fy <= 0:
            raise InvalidRequest("focal lengths must be > 0 [px]", field="intrinsics.fx")

    def matrix(self) -> np.ndarray:
        """The camera matrix K, shape (3, 3)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def dist(self) -> np.ndarray:
        """The distortion coefficients as OpenCV takes them, shape (n,)."""
        return np.asarray(self.distortion, dtype=np.float64)

    def fovy(self) -> float:
        """The vertical field of view [rad] (needs ``height``)."""
        return 2.0 * math.atan(self.height / 2.0 / self.fy)

    @classmethod
    def from_mapping(cls, data: object, *, field: str = "intrinsics") -> Intrinsics:
        """From the wire's ``{"fx", "fy", "cx", "cy"}`` (optionally ``width``, ``height``,
        ``distortion``)."""
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object with fx, fy, cx, cy", field=field)
        missing = [k for k in ("fx", "fy", "cx", "cy") if k not in data]
        if missing:
            raise InvalidRequest(f"missing {', '.join(missing)}", field=field)
        return cls(fx=data["fx"], fy=data["fy"], cx=data["cx"], cy=data["cy"],
                   width=int(data.get("width", 0)), height=int(data.get("height", 0)),
                   distortion=tuple(float(x) for x in data.get("distortion", ())))

    def to_dict(self) -> dict[str, object]:
        return {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy,
                "width": self.width, "height": self.height,
                "distortion": list(self.distortion)}


def ideal(width: int, height: int, horizontal_fov: float) -> Intrinsics:
    """An ideal pinhole of ``width`` x ``height`` [px] and ``horizontal_fov`` [rad], with
    square pixels (as Gazebo's camera sensor renders)."""
    if width <= 0 or height <= 0:
        raise InvalidRequest(f"image size {width} x {height} must be > 0 [px]",
                             field="intrinsics")
    if not 0.0 < horizontal_fov < math.pi:
        raise InvalidRequest(f"horizontal fov {horizontal_fov!r} must be in (0, pi) [rad]",
                             field="intrinsics")
    f = width / 2.0 / math.tan(horizontal_fov / 2.0)
    return Intrinsics(fx=f, fy=f, cx=(width - 1) / 2.0, cy=(height - 1) / 2.0,
                      width=width, height=height)


def _matrix_data(value: object, n: int, field: str) -> list[float]:
    data = value.get("data") if isinstance(value, Mapping) else value
    if not isinstance(data, Sequence) or len(data) < n:
        raise InvalidRequest(f"must hold {n} numbers", field=field)
    try:
        return [float(x) for x in data]
    except (TypeError, ValueError):
        raise InvalidRequest("must hold numbers", field=field) from None


def from_camera_info(text: str) -> Intrinsics:
    """From a ROS ``camera_info`` YAML: the calibration file ``camera_calibration``
    writes (``image_width``, ``camera_matrix.data``, ``distortion_coefficients.data``) or
    a ``sensor_msgs/CameraInfo`` echoed as YAML (``width``, ``k``, ``d``)."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise InvalidRequest(f"not YAML: {e}", field="intrinsics") from None
    if not isinstance(doc, Mapping):
        raise InvalidRequest("a camera_info YAML must be a mapping", field="intrinsics")
    if "camera_matrix" in doc:
        k = _matrix_data(doc["camera_matrix"], 9, "intrinsics.camera_matrix")
        d = doc.get("distortion_coefficients", ())
        w, h = doc.get("image_width", 0), doc.get("image_height", 0)
    elif "k" in doc or "K" in doc:
        k = _matrix_data(doc.get("k", doc.get("K")), 9, "intrinsics.k")
        d = doc.get("d", doc.get("D", ()))
        w, h = doc.get("width", 0), doc.get("height", 0)
    else:
        raise InvalidRequest("no camera_matrix (or k) in the camera_info YAML",
                             field="intrinsics")
    dist = _matrix_data(d, 0, "intrinsics.distortion") if d else []
    return Intrinsics(fx=k[0], fy=k[4], cx=k[2], cy=k[5], width=int(w), height=int(h),
                      distortion=tuple(dist) if any(dist) else ())


@dataclass(frozen=True)
class CameraSensor:
    """A ``<gazebo reference=LINK><sensor type="camera">`` of the model.

    Attributes:
        link: the link it is on; name: the sensor's name.
        width, height: [px]; horizontal_fov: [rad]; update_rate: [Hz] (0 if not given).
    """

    link: str
    name: str
    width: int
    height: int
    horizontal_fov: float
    update_rate: float = 0.0

    def intrinsics(self) -> Intrinsics:
        return ideal(self.width, self.height, self.horizontal_fov)


def _float(el: ET.Element | None, default: float) -> float:
    if el is None or el.text is None:
        return default
    return float(el.text.strip())


def camera_sensors(urdf_text: str) -> tuple[CameraSensor, ...]:
    """Every Gazebo camera sensor of an expanded URDF, in document order (SDF's defaults
    where a value is missing: 320 x 240 px, 1.047 rad)."""
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as e:
        raise InvalidRequest(f"the model is not XML: {e}", field="camera") from None
    out = []
    for gz in root.iter("gazebo"):
        link = gz.get("reference")
        if not link:
            continue
        for sensor in gz.iter("sensor"):
            if sensor.get("type") not in ("camera", "rgbd_camera", "depth"):
                continue
            cam = sensor.find("camera")
            image = cam.find("image") if cam is not None else None
            out.append(CameraSensor(
                link=link, name=sensor.get("name", link),
                width=int(_float(image.find("width") if image is not None else None, 320)),
                height=int(_float(image.find("height") if image is not None else None, 240)),
                horizontal_fov=_float(cam.find("horizontal_fov") if cam is not None else None,
                                      1.047),
                update_rate=_float(sensor.find("update_rate"), 0.0)))
    return tuple(out)
