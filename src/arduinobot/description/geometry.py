"""A link's geometry: a shape of the scene's (:mod:`arduinobot.scene.shapes`), so the
robot and what is around it are one shape model.

A URDF ``<box>``, ``<sphere>`` or ``<cylinder>`` is the scene's :class:`Box`,
:class:`Sphere` or :class:`Cylinder` (built as written: a URDF may give a zero size,
which ``arduinobot check`` reports, where a scene object is refused); a ``<mesh>`` is a
:class:`MeshFile`: its URI, the file it resolved to and its per-axis scale.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.shapes import Box, Cylinder, Shape, Sphere
from arduinobot.scene.shapes.base import bvh
from arduinobot.scene.shapes.mesh import mesh_unit_inertia

if TYPE_CHECKING:
    import fcl
    import trimesh


@dataclass(frozen=True)
class MeshFile(Shape):
    """A URDF ``<mesh>``: its triangles are its file's, scaled, in its frame [m].

    Attributes:
        uri: the ``filename`` as written in the URDF.
        path: where ``uri`` resolved on this machine; None if it did not.
        scale: the per-axis scale [-] (a millimetre CAD export: 0.001).
    """

    uri: str
    path: Path | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    kind: ClassVar[str] = "mesh"  # the URDF's tag, as the primitives' kinds are theirs
    portable: ClassVar[bool] = False

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        # not a wire shape (it is not registered): only the URDF reader builds one
        raise InvalidRequest("a URDF mesh is read from its URDF, not from JSON", field=field)

    @property
    def source(self) -> Path | None:
        return self.path

    @property
    def source_scale(self) -> tuple[float, float, float]:
        return self.scale

    def content_key(self) -> tuple:
        if self.path is None:
            return self.key()
        return ("mesh", hashlib.sha256(self.path.read_bytes()).digest(), self.scale)

    def triangles(self) -> trimesh.Trimesh:
        """Its file's triangles, scaled (a copy of the shared cached mesh).

        Raises:
            MeshNotFound: its URI did not resolve, or the file is gone.
            MeshLoadError: the file is not a mesh.
        """
        from arduinobot.description.errors import MeshNotFound
        from arduinobot.description.meshes import load_mesh

        if self.path is None:
            raise MeshNotFound(f"mesh '{self.uri}' did not resolve")
        return load_mesh(self.path, self.scale).copy()

    def unit_inertia(self) -> tuple[np.ndarray, np.ndarray]:
        return mesh_unit_inertia(self.triangles())

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return bvh(self.triangles())


#: a URDF geometry: one of the scene's primitives, or a mesh file
Geometry = Box | Sphere | Cylinder | MeshFile
