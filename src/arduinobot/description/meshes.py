"""Loading mesh files as trimesh objects in metres, cached by file and scale.

Meshes are the slow part of loading a model (a real part has up to 55k triangles), so
each (file, modification time, scale) is read once per process.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import trimesh

from arduinobot.description.errors import DescriptionError, MeshLoadError, MeshNotFound


class Placed(Protocol):
    """A geometry placed in its link (:class:`arduinobot.description.model.Shape`),
    as :func:`shape_mesh` reads it (a protocol: the model imports the geometry, whose
    mesh files this module loads)."""

    @property
    def geometry(self) -> Any: ...

    @property
    def origin(self) -> Any: ...

_log = logging.getLogger(__name__)
_cache: dict[tuple[str, int, tuple[float, float, float]], trimesh.Trimesh] = {}
_cache_lock = threading.Lock()


def load_mesh(path: Path, scale: tuple[float, float, float] = (1.0, 1.0, 1.0), *,
              element: str | None = None) -> trimesh.Trimesh:
    """Read a mesh file and apply its URDF scale. The result is shared: do not modify it.

    Raises:
        MeshNotFound: the file does not exist.
        MeshLoadError: the file is not a mesh trimesh can read, or is empty.
    """
    try:
        stat = path.stat()
    except OSError:
        raise MeshNotFound(f"{path} does not exist", file=path, element=element) from None
    key = (str(path), stat.st_mtime_ns, (float(scale[0]), float(scale[1]), float(scale[2])))
    with _cache_lock:
        hit = _cache.get(key)
    if hit is not None:
        return hit
    try:
        loaded = trimesh.load(str(path), force="mesh", process=True)
    except Exception as e:  # trimesh raises many kinds for a bad file
        raise MeshLoadError(f"cannot read mesh {path}: {type(e).__name__}: {e}", file=path,
                            element=element, hint="export it as STL, OBJ, PLY, DAE or GLB") from e
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshLoadError(f"cannot read a mesh from {path}: no triangles in it", file=path,
                            element=element, hint="export it as binary STL, OBJ, PLY, DAE or GLB")
    mesh = loaded.copy()
    mesh.apply_scale(np.asarray(scale, dtype=float))
    mesh.vertices.flags.writeable = False
    mesh.faces.flags.writeable = False
    with _cache_lock:
        _cache[key] = mesh
    _log.debug("loaded %s: %d triangles", path, len(mesh.faces))
    return mesh


def shape_mesh(shape: Placed, *, element: str | None = None) -> trimesh.Trimesh:
    """The shape's triangles in its link's frame [m] (origin and scale applied).

    Raises:
        MeshNotFound, MeshLoadError: a mesh that did not resolve or does not load, the
            error naming ``element``.
    """
    try:
        base = shape.geometry.triangles()  # a new mesh: moved in place
    except DescriptionError as e:
        raise e.at(element)  # noqa: B904 -- the same error, its cause kept
    return base.apply_transform(shape.origin.matrix())


def concatenate(parts: Sequence[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The triangles of ``parts`` as one mesh (trimesh's own concatenate is typed as
    returning any geometry; for meshes it returns a mesh)."""
    mesh = trimesh.util.concatenate(list(parts))
    if not isinstance(mesh, trimesh.Trimesh):
        raise TypeError(f"trimesh concatenated meshes into a {type(mesh).__name__}")
    return mesh
