"""The kept scene on disk: where an instance keeps it, its mesh files beside it, and a
file written so that a crash at any moment leaves the old scene or the new one."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.state import SceneState


class SceneFile:
    """The scene kept on disk: JSON written to a temporary file, synced, then renamed
    over the old one, so a crash at any moment leaves the old scene or the new one."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)

    def load(self) -> dict[str, Any] | None:
        """The scene file's JSON, or None if there is none yet.

        Raises:
            InvalidRequest: the file is not a scene (naming the file).
        """
        try:
            text = self.path.read_text("utf-8")
        except FileNotFoundError:
            return None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise InvalidRequest(f"scene file {self.path} is not JSON: {e}") from None
        if not isinstance(data, dict):
            raise InvalidRequest(f"scene file {self.path} is not a scene object")
        return data

    def save(self, state: SceneState) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=f".{self.path.name}-",
                                   suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(state.to_json(), f, separators=(",", ":"))
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        # the rename itself must reach the disk before the apply is acknowledged
        dir_fd = os.open(self.path.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)


def default_scene_file(prefix: str) -> Path:
    """Where ``arduinobot serve`` keeps the scene of ``prefix`` by default:
    ``$ARDUINOBOT_STATE``, else ``$XDG_STATE_HOME/arduinobot``, else
    ``~/.local/state/arduinobot``; one file per prefix."""
    base = os.environ.get("ARDUINOBOT_STATE")
    if not base:
        xdg = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
        base = str(Path(xdg) / "arduinobot")
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in prefix)
    return Path(base) / f"scene-{safe}.json"


def mesh_dir_for(scene_file: str | os.PathLike[str]) -> Path:
    """The folder of a scene file's canonical mesh files (beside it)."""
    return Path(scene_file).parent / "meshes"
