"""The map of marker ids to objects: which object a marker sits on, its shape and size,
and where on it the marker is (``objects.yaml`` beside tasks.yaml, or a request's
``markers``).

A marker's frame is OpenCV's: origin at the marker's centre, x to the right and y up as
the marker is printed, z out of the printed face. ``offset`` is that frame in the
object's frame: a marker centred on a box's +x face, printed upright, is
``{"xyz": [sx / 2, 0, 0], "rpy": [pi / 2, 0, pi / 2]}``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal, cast

import yaml

from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.model import Origin
from arduinobot.scene.shapes import Shape, kinds, shape_class

Dictionary = Literal["4x4_50", "4x4_100", "4x4_250", "5x5_50", "5x5_100", "5x5_250",
                     "6x6_50", "6x6_250", "apriltag_16h5", "apriltag_25h9",
                     "apriltag_36h11"]
DICTIONARIES: tuple[str, ...] = ("4x4_50", "4x4_100", "4x4_250", "5x5_50", "5x5_100",
                                 "5x5_250", "6x6_50", "6x6_250", "apriltag_16h5",
                                 "apriltag_25h9", "apriltag_36h11")


def _markable() -> dict[str, type[Shape]]:
    """The shapes an object with a marker may have, by name: those given by their
    dimensions (:attr:`~arduinobot.scene.shapes.Shape.portable`), not a file of the
    server's (a marker map comes in a request too)."""
    return {k: c for k in kinds() if (c := shape_class(k)).portable}


def cv_dictionary_name(name: str) -> str:
    """OpenCV's constant for a dictionary name (``4x4_50`` -> ``DICT_4X4_50``)."""
    return "DICT_" + name.upper()


def _vec(value: object, n: int, where: str, *, positive: bool = False) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise InvalidRequest(f"{value!r} must be {n} numbers", field=where)
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise InvalidRequest(f"{value!r} must be {n} numbers", field=where) from None
    if not all(math.isfinite(x) for x in v) or (positive and min(v) <= 0):
        raise InvalidRequest(f"{value!r} must be {n} finite numbers"
                             + (" > 0 [m]" if positive else ""), field=where)
    return v


@dataclass(frozen=True)
class MarkedObject:
    """An object a marker sits on.

    Attributes:
        id: the scene object's id.
        geometry: its shape (:mod:`arduinobot.scene.shapes`), centred on the object's
            frame: one given by its dimensions (box, sphere, cylinder), not a file.
        offset: the marker's frame in the object's frame.
    """

    id: str
    geometry: Shape
    offset: Origin = field(default_factory=Origin)

    def extent(self) -> float:
        """The farthest the object's surface reaches from its centre [m]."""
        return self.geometry.reach()


@dataclass(frozen=True)
class MarkerMap:
    """Marker ids to objects.

    Attributes:
        dictionary: the ArUco/AprilTag family.
        size: a marker's printed side, black border included [m].
        objects: marker id -> the object it sits on.
    """

    dictionary: Dictionary
    size: float
    objects: Mapping[int, MarkedObject]

    @classmethod
    def from_mapping(cls, data: object, *, where: str = "markers") -> MarkerMap:
        """From the wire's/``objects.yaml``'s ``{"dictionary", "size", "objects": {"3":
        {"id", "shape", "size" | "radius" [, "length"], "offset": {"xyz", "rpy"}}}}``."""
        if not isinstance(data, Mapping):
            raise InvalidRequest("must be an object with dictionary, size, objects", field=where)
        extra = sorted(set(data) - {"dictionary", "size", "objects"})
        if extra:
            raise InvalidRequest(f"unknown field(s) {', '.join(extra)}", field=where)
        d = data.get("dictionary", "4x4_50")
        if d not in DICTIONARIES:
            raise InvalidRequest(f"{d!r} is not one of {', '.join(DICTIONARIES)}",
                                 field=f"{where}.dictionary")
        size = data.get("size")
        if isinstance(size, bool) or not isinstance(size, (int, float)) \
                or not math.isfinite(size) or size <= 0:
            raise InvalidRequest(f"{size!r} must be the marker's side > 0 [m]",
                                 field=f"{where}.size")
        objs = data.get("objects")
        if not isinstance(objs, Mapping) or not objs:
            raise InvalidRequest("must map marker ids to objects", field=f"{where}.objects")
        out: dict[int, MarkedObject] = {}
        for key, o in objs.items():
            w = f"{where}.objects.{key}"
            try:
                mid = int(key)
            except (TypeError, ValueError):
                raise InvalidRequest(f"{key!r} is not a marker id", field=w) from None
            out[mid] = _object(o, w)
        ids = [o.id for o in out.values()]
        dup = sorted({i for i in ids if ids.count(i) > 1})
        if dup:
            raise InvalidRequest(f"object id(s) {', '.join(dup)} on more than one marker",
                                 field=f"{where}.objects")
        return cls(dictionary=cast(Dictionary, d), size=float(size), objects=out)


def _object(o: object, w: str) -> MarkedObject:
    if not isinstance(o, Mapping):
        raise InvalidRequest("must be an object with id, shape and its size", field=w)
    extra = sorted(set(o) - {"id", "shape", "offset"}
                   - {f for c in _markable().values() for f in c.field_names()})
    if extra:
        raise InvalidRequest(f"unknown field(s) {', '.join(extra)}", field=w)
    oid = o.get("id")
    if not isinstance(oid, str) or not oid:
        raise InvalidRequest("must be a non-empty string", field=f"{w}.id")
    markable, shape = _markable(), o.get("shape")
    cls = markable.get(shape) if isinstance(shape, str) else None
    if cls is None:
        raise InvalidRequest(f"{shape!r} is not one of {', '.join(markable)}",
                             field=f"{w}.shape")
    # each kind reads its own fields; another kind's (a box's radius) is let be, as ever
    geometry = cls.from_json({k: o.get(k) for k in cls.field_names()}, where=w)
    off = o.get("offset", {})
    if not isinstance(off, Mapping) or sorted(set(off) - {"xyz", "rpy"}):
        raise InvalidRequest("must be {xyz, rpy}", field=f"{w}.offset")
    offset = Origin(xyz=cast(tuple[float, float, float],
                             _vec(off.get("xyz", [0, 0, 0]), 3, f"{w}.offset.xyz")),
                    rpy=cast(tuple[float, float, float],
                             _vec(off.get("rpy", [0, 0, 0]), 3, f"{w}.offset.rpy")))
    return MarkedObject(id=oid, geometry=geometry, offset=offset)


def load_marker_map(text: str) -> MarkerMap:
    """An ``objects.yaml``: the ``markers`` mapping (or the file's top level)."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise InvalidRequest(f"not YAML: {e}", field="markers") from None
    if isinstance(doc, Mapping) and "markers" in doc:
        doc = doc["markers"]
    return MarkerMap.from_mapping(doc)
