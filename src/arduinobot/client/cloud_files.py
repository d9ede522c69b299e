"""Point-cloud files a user has, read into points to send (``scene add-cloud``).

- ``.ply``: trimesh (already the collision layer's mesh library; reads ASCII and
  binary PLY, a vertex-only cloud as a ``PointCloud``, a mesh's vertices otherwise).
- ``.pcd``: pypcd4 (PCL's format in all three encodings, binary_compressed too; kept up
  on PyPI in 2026, where pypcd and its forks stopped in 2018-2023; pure Python on numpy,
  no Open3D's 400 MB). Only in the ``cloud`` extra: imported when a .pcd is read.
- ``.xyz``, ``.csv``, ``.txt``: numpy; comma or blank separated, x y z in the first three
  columns (more columns, as intensity or colour, are ignored), a header line skipped.

Each refusal is an :class:`~arduinobot.contract.errors.InvalidRequest` naming ``file``.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

import numpy as np

from arduinobot.contract.caps import MAX_CLOUD_BYTES
from arduinobot.contract.errors import InvalidRequest

SUFFIXES = (".ply", ".pcd", ".xyz", ".csv", ".txt")
#: Largest file read [bytes]: a text cloud of the cap's points takes ~4x the binary.
MAX_FILE_BYTES = 8 * MAX_CLOUD_BYTES


def read_cloud_file(path: str | os.PathLike[str], *, field: str = "file") -> np.ndarray:
    """The points of a .ply, .pcd, .xyz or .csv file, shape (n, 3) [file units], NaNs
    kept (the service drops and counts them)."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise InvalidRequest(f"'{p.name}' is not one of {', '.join(SUFFIXES)}", field=field)
    if not p.is_file():
        raise InvalidRequest(f"'{p}' is not a file", field=field)
    if p.stat().st_size > MAX_FILE_BYTES:
        raise InvalidRequest(f"'{p.name}' is larger than {MAX_FILE_BYTES} bytes",
                             field=field, details={"limit": MAX_FILE_BYTES})
    try:
        if suffix == ".ply":
            pts = _ply(p)
        elif suffix == ".pcd":
            pts = _pcd(p)
        else:
            pts = _text(p)
    except InvalidRequest:
        raise
    except Exception as e:  # noqa: BLE001 -- any parser failure on a user's file is a refusal
        raise InvalidRequest(f"'{p.name}' is not a readable {suffix[1:].upper()} cloud "
                             f"({type(e).__name__}: {str(e)[:200]})", field=field) from None
    pts = np.asarray(pts, float).reshape(-1, 3) if np.size(pts) else np.empty((0, 3))
    if len(pts) == 0:
        raise InvalidRequest(f"'{p.name}' holds no point", field=field)
    return pts


def _ply(p: Path) -> np.ndarray:
    import trimesh

    loaded: Any = trimesh.load(str(p), file_type="ply", process=False)
    return np.asarray(loaded.vertices, float)


def _pcd(p: Path) -> np.ndarray:
    from pypcd4 import PointCloud

    pc = PointCloud.from_path(p)
    missing = [a for a in "xyz" if a not in pc.fields]
    if missing:
        raise InvalidRequest(f"'{p.name}' has no {', '.join(missing)} field (fields: "
                             f"{', '.join(pc.fields)})", field="file")
    return np.asarray(pc.numpy(("x", "y", "z")), float)


def _text(p: Path) -> np.ndarray:
    text = p.read_text(encoding="utf-8", errors="strict")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if lines and not _numeric(lines[0]):
        lines = lines[1:]  # a header: x,y,z
    body = "\n".join(ln.replace(",", " ") for ln in lines)
    if not body:
        return np.empty((0, 3))
    if any(len(ln.split()) < 3 for ln in body.splitlines()):
        raise InvalidRequest(f"'{p.name}' has a row of fewer than 3 columns (x y z)",
                             field="file")
    return np.loadtxt(io.StringIO(body), ndmin=2, usecols=(0, 1, 2))


def _numeric(line: str) -> bool:
    try:
        [float(v) for v in line.replace(",", " ").split()]
    except ValueError:
        return False
    return True
