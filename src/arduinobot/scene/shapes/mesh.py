"""A mesh file in metres: ``mesh_path`` (a kept-scene object sends it inline)."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, cast

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.shapes.base import Shape, box_unit_inertia, bvh
from arduinobot.scene.shapes.registry import register

if TYPE_CHECKING:
    import fcl
    import trimesh


@register
@dataclass(frozen=True)
class Mesh(Shape):
    """A mesh file (STL, OBJ, PLY, ...) in metres, in its frame; ``mesh_path`` on this
    machine (an inline mesh is written to one first: :mod:`arduinobot.scene.mesh_codec`)."""

    mesh_path: str
    kind: ClassVar[str] = "mesh"
    portable: ClassVar[bool] = False
    inline: ClassVar[tuple[str, ...]] = ("mesh", "scale")

    @classmethod
    def stored(cls, data: Mapping[str, Any], *, where: str, folder: Path) -> dict[str, Any]:
        if "mesh" not in data:
            raise InvalidRequest("a mesh object needs mesh {format, data}",
                                 field=f"{where}.mesh")
        from arduinobot.scene.mesh_codec import decode_mesh, scale_of

        mesh = decode_mesh(data["mesh"], scale=scale_of(data.get("scale"), f"{where}.scale"),
                           field=f"{where}.mesh")
        out = {k: v for k, v in data.items() if k not in cls.inline}
        out["mesh_path"] = str(mesh.write(folder))
        return out

    @classmethod
    def summary(cls, data: Mapping[str, Any]) -> str:
        if "mesh" not in data:  # a file of this machine's
            return f"mesh file {data.get('mesh_path')}"
        import base64

        size = len(base64.b64decode(data["mesh"]["data"]))
        return f"{data['mesh']['format']} mesh, {size} bytes, scale {data.get('scale', 1)}"

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        if not isinstance(value, str) or not value or not Path(value).is_file():
            raise InvalidRequest(f"mesh file {value!r} does not exist", field=field)
        return value

    def content_key(self) -> tuple:
        # the bytes: the same content under another name, or a file rewritten in place,
        # is told apart
        with open(self.mesh_path, "rb") as f:
            return ("mesh", hashlib.sha256(f.read()).digest())

    @property
    def source(self) -> Path:
        return Path(self.mesh_path)

    def triangles(self) -> trimesh.Trimesh:
        import trimesh

        return cast(trimesh.Trimesh, trimesh.load(self.mesh_path, force="mesh"))  # one mesh

    def unit_inertia(self) -> tuple[np.ndarray, np.ndarray]:
        return mesh_unit_inertia(self.triangles())

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return bvh(self.triangles())


def mesh_unit_inertia(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's centroid shape (3,) [m] and inertia per kg about it shape (3, 3) [m^2] as
    a uniform solid; a mesh that is not closed: its bounding box's."""
    if mesh.is_watertight and mesh.volume > 0:
        return (np.asarray(mesh.center_mass, float),
                np.asarray(mesh.moment_inertia, float) / float(mesh.mass))
    lo, hi = mesh.bounds  # not closed: its bounding box's
    return (lo + hi) / 2, box_unit_inertia(hi - lo)
