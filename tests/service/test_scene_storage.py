"""A disk that refuses the kept scene's writes answers STORAGE (issue 39, item 8), not
INTERNAL with the OS's text and the server's paths: the mesh file and the scene file
alike, nothing changed, no half-written file left. The disk's refusal is real: the
process's file size limit (RLIMIT_FSIZE, SIGXFSZ ignored) makes the kernel fail the
write with EFBIG, as a full disk fails it with ENOSPC."""

from __future__ import annotations

import base64
import errno
import json
import resource
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import trimesh

from arduinobot.client import errors as client_errors
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import StorageError
from arduinobot.service.scene.sync import SceneService
from tests.service.test_scene_meshes import _apply, _files, scene  # noqa: F401 -- a fixture

LIMIT = 2048  # [bytes] the largest file this process may write while it holds


@contextmanager
def _small_disk() -> Iterator[None]:
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    old = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, old)


def _refused(body: dict[str, Any], tmp_path: Path) -> dict[str, Any]:
    err = body["error"]
    assert err["code"] == Code.STORAGE, body
    assert err["details"]["errno"] == "EFBIG"
    assert str(tmp_path) not in json.dumps(body) and "/" not in err["message"]
    return err


def test_a_refused_mesh_write_is_storage_and_changes_nothing(
        scene: SceneService, tmp_path: Path) -> None:  # noqa: F811
    ball = trimesh.creation.icosphere(subdivisions=3).export(file_type="stl")
    assert len(ball) > LIMIT
    mesh = {"id": "ball", "shape": "mesh", "xyz": [1.5, 1.5, 1.5],
            "mesh": {"format": "stl", "data": base64.b64encode(ball).decode()}}
    with _small_disk():
        body = _apply(scene, {"add": [mesh]})
    assert "mesh file" in _refused(body, tmp_path)["message"]
    assert scene.state.revision == 0 and _files(scene) == []


def test_a_refused_scene_file_is_storage_and_keeps_the_old_scene(
        scene: SceneService, tmp_path: Path) -> None:  # noqa: F811
    assert _apply(scene, {"add": [{"id": "t", "shape": "box", "size": [1, 1, 1]}]})[
        "revision"] == 1
    before = scene.file.path.read_bytes()
    boxes = [{"id": f"b{i}", "shape": "box", "size": [0.1, 0.1, 0.1], "xyz": [1, 1, i / 10]}
             for i in range(40)]
    with _small_disk():
        body = _apply(scene, {"add": boxes})
    assert "scene's file" in _refused(body, tmp_path)["message"]
    assert scene.state.revision == 1 and scene.file.path.read_bytes() == before
    assert [p.name for p in scene.file.path.parent.iterdir() if p.suffix == ".tmp"] == []


def test_the_client_knows_storage_and_the_words_have_no_path(tmp_path: Path) -> None:
    # ENOSPC as a full disk gives it, from the kernel (/dev/full)
    with pytest.raises(OSError) as e, open("/dev/full", "wb", buffering=0) as f:
        f.write(b"x")
    assert e.value.errno == errno.ENOSPC
    err = StorageError.of(e.value, "the scene's file")
    assert err.code == Code.STORAGE and err.details == {"errno": "ENOSPC"}
    assert "no space left on device" in err.message and "/dev" not in err.message
    reply = {"error": {"code": "STORAGE", "message": err.message, "details": err.details}}
    assert isinstance(client_errors.error_from_reply(reply), client_errors.StorageError)
