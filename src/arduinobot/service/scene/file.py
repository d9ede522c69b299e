"""The kept scene on disk: where an instance keeps it, its mesh files beside it, and a
file written so that a crash at any moment leaves the old scene or the new one."""

from __future__ import annotations

import glob
import hashlib
import json
import logging
import os
import tempfile
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import orjson

from arduinobot.contract.errors import InvalidRequest, StorageError
from arduinobot.scene.state import SceneState

_log = logging.getLogger(__name__)

#: How old a scene file's temporary file must be to be a killed writer's [s] (a live
#: writer renames its own within a second).
STALE_TMP_AGE = 60.0
#: The key of a scene file that records which robot it was kept for.
OWNER_KEY = "robot"


class SceneFile:
    """The scene kept on disk: JSON written to a temporary file, synced, then renamed
    over the old one, so a crash at any moment leaves the old scene or the new one."""

    def __init__(self, path: str | os.PathLike[str], *,
                 owner: Mapping[str, str] | None = None) -> None:
        """``owner``: the robot this scene is kept for (:func:`scene_owner`), written
        into the file so another robot's service can say the scene is not its own."""
        self.path = Path(path)
        self.owner = dict(owner) if owner is not None else None

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

    def set_aside(self) -> Path:
        """Rename the file to ``<name>.unreadable-<UTC time>`` beside it (kept for its
        owner to read, never loaded again); its new path."""
        aside = self.path.with_name(
            f"{self.path.name}.unreadable-{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}")
        os.replace(self.path, aside)
        return aside

    def clean(self, *, older_than: float = STALE_TMP_AGE) -> int:
        """Remove the temporary files of this scene file that a killed writer left
        (``.<name>-*.tmp``, last written over ``older_than`` [s] ago: a live writer's is
        younger); the number removed."""
        removed = 0
        now = time.time()
        try:
            stale = list(self.path.parent.glob(f".{glob.escape(self.path.name)}-*.tmp"))
        except OSError as e:
            _log.warning("scene: cannot list %s for stale temporary files: %s",
                         self.path.parent, e)
            return 0
        for f in stale:
            try:
                old = now - f.stat().st_mtime > older_than
            except FileNotFoundError:
                continue
            except OSError as e:
                _log.warning("scene: cannot read the temporary file %s: %s", f, e)
                continue
            if old and _remove(f, "stale temporary file"):
                removed += 1
        if removed:
            _log.info("scene: %d temporary file(s) of a killed writer removed beside %s",
                      removed, self.path)
        return removed

    def save(self, state: SceneState) -> None:
        """Write ``state`` (see the class).

        Raises:
            StorageError: the disk refused it (full, read-only: ``details.errno``); the
                old file stands. The path and the OS's words go to the log only.
        """
        try:
            self._save(state)
        except OSError as e:
            _log.error("scene: could not write %s: %s", self.path, e)
            raise StorageError.of(e, "the scene's file") from None

    def _save(self, state: SceneState) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=f".{self.path.name}-",
                                   suffix=".tmp")
        try:
            body = state.to_json()
            if self.owner is not None:
                body[OWNER_KEY] = self.owner
            # orjson: a scene with a 300,000-point cloud writes in 5 ms, json.dump's 17
            with os.fdopen(fd, "wb") as f:
                f.write(orjson.dumps(body))
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


def _safe(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in text)


def scene_owner(robot_name: str, model: str | os.PathLike[str] | None) -> dict[str, str]:
    """Who a kept scene belongs to: the robot's name and its model file. Every robot
    the command line serves is under the prefix ``arduinobot`` by default, and two models
    may share a name (the shipped arduinobot and the course's printed one, ten times
    smaller), so the model file is part of it."""
    return {"name": robot_name, "model": str(model) if model is not None else ""}


def owner_key(owner: Mapping[str, str]) -> str:
    """A file-name-safe key of ``owner``: its name and a hash of its model file."""
    digest = hashlib.sha256(owner.get("model", "").encode("utf-8")).hexdigest()[:10]
    return f"{_safe(owner.get('name', 'robot'))}-{digest}"


def state_dir() -> Path:
    """``$ARDUINOBOT_STATE``, else ``$XDG_STATE_HOME/arduinobot``, else
    ``~/.local/state/arduinobot``."""
    base = os.environ.get("ARDUINOBOT_STATE")
    if not base:
        xdg = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
        base = str(Path(xdg) / "arduinobot")
    return Path(base)


def default_scene_file(prefix: str, owner: Mapping[str, str] | None = None) -> Path:
    """Where ``arduinobot serve`` keeps the scene of ``prefix`` by default, in
    :func:`state_dir`: one file per prefix and robot (``owner``, :func:`scene_owner`), so
    one robot's obstacles never appear in another's world."""
    if owner is None:
        return state_dir() / f"scene-{_safe(prefix)}.json"
    return state_dir() / f"scene-{_safe(prefix)}--{owner_key(owner)}.json"


def foreign_owner(data: Mapping[str, Any], owner: Mapping[str, str] | None) -> str | None:
    """Why the scene file ``data`` is not ``owner``'s (a sentence naming both robots), or
    None when it is, or when either side does not say."""
    kept = data.get(OWNER_KEY)
    if owner is None or not isinstance(kept, Mapping):
        return None
    if kept.get("name") == owner.get("name") and kept.get("model") == owner.get("model"):
        return None
    return (f"it was kept for robot '{kept.get('name')}' (model {kept.get('model') or '?'}), "
            f"not for '{owner.get('name')}' (model {owner.get('model') or '?'})")


def mesh_dir_for(scene_file: str | os.PathLike[str]) -> Path:
    """The folder of a scene file's canonical mesh files (beside it), its own: files no
    revision of this scene uses are collected (:func:`collect_meshes`), which a folder
    shared with another scene's would make unsafe. They are a cache: the scene file
    holds each mesh inline, and :func:`arduinobot.scene.change.restore` writes them again."""
    p = Path(scene_file)
    return p.parent / "meshes" / p.stem


def mesh_files(state: SceneState) -> set[Path]:
    """The files ``state``'s objects are read from (free, fixed in a link, carried)."""
    shapes = [o.obstacle.geometry for o in state.objects]
    shapes += [a.attached.shape.geometry for a in state.attached]
    return {Path(src) for g in shapes if (src := g.source) is not None}


def collect_meshes(folder: Path, keep: Iterable[SceneState]) -> int:
    """Remove every mesh file of ``folder`` that no state of ``keep`` uses (a refused
    apply's, a removed object's) and every temporary file a killed writer left; the
    number removed. Only a scene's own writer calls it, holding its lock (no write is
    under way in ``folder``)."""
    used = {p.resolve() for st in keep for p in mesh_files(st)}
    removed = 0
    try:
        entries = list(folder.iterdir())
    except FileNotFoundError:
        return 0
    except OSError as e:  # never in the way of the apply it follows: said, not raised
        _log.warning("scene: cannot list %s to collect its mesh files: %s", folder, e)
        return 0
    for f in entries:
        stale = (f.suffix == ".stl" and f.resolve() not in used) or \
            (f.name.startswith(".mesh-") and f.suffix == ".tmp")
        if stale and f.is_file() and _remove(f, "unused mesh file"):
            removed += 1
    if removed:
        _log.info("scene: %d mesh file(s) no revision uses removed from %s", removed, folder)
    return removed


def _remove(f: Path, what: str) -> bool:
    """Remove ``f``; whether it was removed (gone already: not by us; refused: said in the
    log, never in the way of the scene change it follows)."""
    try:
        f.unlink()
        return True
    except FileNotFoundError:
        return False
    except OSError as e:
        _log.warning("scene: cannot remove the %s %s: %s", what, f, e)
        return False


def object_named(data: Mapping[str, Any], field: str | None) -> str | None:
    """The object a scene's ``field`` (``objects[1].radius``, ``attached[0].link``) lies
    in, as a user finds it in the file: ``"object 'ball' (objects[1])"``; None when the
    field is not inside one."""
    if not field:
        return None
    for key in ("objects", "attached"):
        if field.startswith(f"{key}["):
            try:
                i = int(field[len(key) + 1:field.index("]")])
                item = data[key][i]
            except (ValueError, LookupError, TypeError):
                return None
            oid = item.get("id") if isinstance(item, Mapping) else None
            what = "carried object" if key == "attached" else "object"
            return f"{what} '{oid}' ({key}[{i}])" if oid is not None else f"{key}[{i}]"
    return None
