"""Mesh scene objects: inline base64 STL (binary or ASCII) or OBJ, decoded, bounded and
written once as a content-addressed file the collision world loads.

Everything here runs on untrusted bytes, so every check comes before the work it bounds:
the base64 text's length, the decoded size (:data:`MAX_MESH_BYTES`), then the parse,
then the triangle count (:data:`MAX_MESH_TRIANGLES`), finiteness, the extent after
scaling (:data:`MAX_MESH_EXTENT`) and a solid's volume (a flat or empty mesh has no convex
hull for the collision world's bounds). Each refusal is an
:class:`~arduinobot.contract.errors.InvalidRequest` naming the field (``add[3].mesh``).

The canonical file is the scaled mesh as binary STL named by the SHA-256 of its bytes, so
an obstacle's ``mesh_path`` is its content key: the planner's world cache
(:meth:`arduinobot.scene.obstacles.Obstacle.key`) then reuses a world for the same geometry
and builds a new one for new geometry, whatever the object's id.
"""

from __future__ import annotations

import hashlib
import io
import logging
import math
import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from arduinobot.contract.errors import InvalidRequest, StorageError
from arduinobot.contract.inline import base64_cap, decode_inline

_log = logging.getLogger(__name__)

MeshFormat = Literal["stl", "obj"]
FORMATS: tuple[MeshFormat, ...] = ("stl", "obj")
#: Largest decoded mesh [bytes] (the base64 text is 4/3 of it).
MAX_MESH_BYTES = 2 * 2**20
#: Longest base64 text of a mesh [characters]: :data:`MAX_MESH_BYTES` encoded.
MAX_MESH_BASE64 = base64_cap(MAX_MESH_BYTES)
#: Most triangles in one mesh.
MAX_MESH_TRIANGLES = 200_000
#: Largest extent of a mesh along any axis, after scaling [m].
MAX_MESH_EXTENT = 100.0
#: A mesh thinner than this fraction of its extent in its flattest direction is flat.
_FLAT = 1e-9


@dataclass(frozen=True)
class MeshGeometry:
    """A validated mesh, scaled, in the object's frame.

    Attributes:
        vertices: shape (v, 3) [m].
        faces: shape (f, 3), vertex indices.
        stl: the canonical binary STL of it.
        sha256: the hex digest of ``stl``: the mesh's content key.
    """

    vertices: np.ndarray
    faces: np.ndarray
    stl: bytes
    sha256: str

    def write(self, directory: str | os.PathLike[str]) -> Path:
        """The canonical file ``<directory>/<sha256>.stl``, written once (atomically:
        a temporary file renamed, so a reader never sees half of it).

        Raises:
            StorageError: the disk refused it (full, read-only: ``details.errno``); the
                path and the OS's words go to the log only.
        """
        d = Path(directory)
        path = d / f"{self.sha256}.stl"
        if path.is_file() and path.stat().st_size == len(self.stl):
            return path
        try:
            self._write(d, path)
        except OSError as e:
            _log.error("mesh: could not write %s: %s", path, e)
            raise StorageError.of(e, "a mesh file") from None
        return path

    def _write(self, d: Path, path: Path) -> None:
        d.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=d, prefix=".mesh-", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(self.stl)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def scale_of(value: object, field: str) -> tuple[float, float, float]:
    """A mesh's ``scale``: one number or three, each finite and > 0 (default 1)."""
    if value is None:
        return (1.0, 1.0, 1.0)
    items: Any = [value] * 3 if isinstance(value, (int, float)) and not isinstance(value, bool) \
        else value
    try:
        vec = tuple(float(v) for v in items)
    except (TypeError, ValueError):
        raise InvalidRequest(f"{value!r} must be a number or 3 numbers", field=field) from None
    if len(vec) != 3 or not all(math.isfinite(v) and v > 0 for v in vec):
        raise InvalidRequest(f"{value!r} must be 1 or 3 finite numbers > 0", field=field)
    return vec


def decode_mesh(spec: Mapping[str, Any], *, scale: Sequence[float] = (1.0, 1.0, 1.0),
                field: str = "mesh") -> MeshGeometry:
    """Decode and validate ``{"format": "stl" | "obj", "data": base64}``.

    Args:
        scale: per-axis factors applied to the vertices (mesh units -> metres).
        field: the field named in refusals (``add[3].mesh``).

    Raises:
        InvalidRequest: not base64, over :data:`MAX_MESH_BYTES`, unreadable as the format,
            over :data:`MAX_MESH_TRIANGLES`, non-finite, over :data:`MAX_MESH_EXTENT`, or
            degenerate (no triangle with area, or flat); ``details.limit`` for caps.
    """
    if not isinstance(spec, Mapping):
        raise InvalidRequest("must be an object {format, data}", field=field)
    fmt = spec.get("format")
    if fmt not in FORMATS:
        raise InvalidRequest(f"{fmt!r} is not one of {', '.join(FORMATS)}",
                             field=f"{field}.format")
    raw = decode_inline(spec.get("data"), cap=MAX_MESH_BYTES, noun="mesh",
                        contents="the mesh file's bytes", field=f"{field}.data")
    vertices, faces = _parse(raw, fmt, field)
    return _validated(vertices, faces, np.asarray(scale, float), field)


def stl_problem(raw: bytes) -> str | None:
    """Why ``raw`` cannot be an STL file, or None if it may be one: a binary STL is
    exactly 84 + 50 x (the count in its header) bytes; any other STL is text beginning
    with ``solid``. (A text file named ``.stl`` would otherwise be read as a binary
    header: 'hello ...' counts 1.7e9 triangles.)"""
    if len(raw) >= 84 and len(raw) == 84 + 50 * int.from_bytes(raw[80:84], "little"):
        return None  # binary (some exporters begin even a binary header with 'solid')
    if raw.lstrip()[:5].lower() == b"solid":
        return None  # text STL
    return (f"not an STL mesh: neither text beginning with 'solid' nor a binary STL, whose "
            f"size is 84 bytes + 50 per triangle its header counts ({len(raw)} bytes here)")


def _parse(raw: bytes, fmt: MeshFormat, field: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh  # the collision world's mesh library; heavy, so only when a mesh comes

    if fmt == "stl":
        problem = stl_problem(raw)
        if problem is not None:
            raise InvalidRequest(problem, field=field)
        # binary STL: the triangle count is in the header, so the cap comes before parsing
        n = int.from_bytes(raw[80:84], "little") if len(raw) >= 84 else 0
        if len(raw) == 84 + 50 * n and n > MAX_MESH_TRIANGLES:
            raise InvalidRequest(f"{n} triangles, more than {MAX_MESH_TRIANGLES}",
                                 field=field, details={"limit": MAX_MESH_TRIANGLES})
    try:
        mesh: Any = trimesh.load(io.BytesIO(raw), file_type=fmt, force="mesh", process=False)
        vertices = np.asarray(mesh.vertices, float).reshape(-1, 3)
        faces = np.asarray(mesh.faces, np.int64).reshape(-1, 3)
    except Exception as e:  # noqa: BLE001 -- any parser failure on user bytes is a refusal
        raise InvalidRequest(f"is not a readable {fmt.upper()} mesh ({type(e).__name__}: "
                             f"{str(e)[:200]})", field=field) from None
    return vertices, faces


def _validated(vertices: np.ndarray, faces: np.ndarray, scale: np.ndarray,
               field: str) -> MeshGeometry:
    import trimesh

    if len(faces) > MAX_MESH_TRIANGLES:
        raise InvalidRequest(f"{len(faces)} triangles, more than {MAX_MESH_TRIANGLES}",
                             field=field, details={"limit": MAX_MESH_TRIANGLES})
    if len(faces) == 0 or len(vertices) < 4:
        raise InvalidRequest("degenerate: the mesh has no triangles", field=field)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InvalidRequest("degenerate: a face refers to a vertex that does not exist",
                             field=field)
    if not np.isfinite(vertices).all():
        raise InvalidRequest("has non-finite vertex coordinates", field=field)
    vertices = vertices * scale
    if not np.isfinite(vertices).all():
        raise InvalidRequest("has non-finite vertex coordinates once scaled", field=field)
    used = vertices[np.unique(faces)]
    extent = used.max(axis=0) - used.min(axis=0)
    if float(extent.max()) > MAX_MESH_EXTENT:
        raise InvalidRequest(f"extends {float(extent.max()):.3g} m, more than "
                             f"{MAX_MESH_EXTENT:g} m (after scale)", field=field,
                             details={"limit": MAX_MESH_EXTENT})
    tri = vertices[faces]
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not float(areas.max()) > 0.0:
        raise InvalidRequest("degenerate: no triangle has an area", field=field)
    # flat (all vertices in one plane): no convex hull, no volume to collide with
    centred = used - used.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if len(sv) < 3 or not sv[2] > _FLAT * max(float(sv[0]), 1e-300):
        raise InvalidRequest("degenerate: the mesh is flat (all its vertices lie in one "
                             "plane); give it a thickness", field=field)
    keep = areas > 0.0  # zero-area triangles add nothing to collide with
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces[keep], process=False)
    stl: Any = mesh.export(file_type="stl")  # binary STL: bytes
    return MeshGeometry(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64),
                        stl, hashlib.sha256(stl).hexdigest())
