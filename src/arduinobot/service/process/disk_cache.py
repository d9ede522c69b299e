"""A content-keyed cache on disk, in the user's cache folder.

``$ARDUINOBOT_CACHE``, else ``$XDG_CACHE_HOME/arduinobot``, else ``~/.cache/arduinobot``.
Each entry is one ``.npz`` written to a temporary file and renamed into place, so
concurrent starts (several workers, several services) never read half a file; a full or
read-only disk costs the speed-up, not the service.
"""

from __future__ import annotations

import logging
import os
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

_log = logging.getLogger(__name__)


class DiskCache:
    """:class:`arduinobot.planner.cache.ArtifactCache` on disk under ``root``."""

    def __init__(self, root: str | Path | None = None) -> None:
        if root is None:  # the user's cache folder (see the module)
            xdg = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
            root = Path(os.environ.get("ARDUINOBOT_CACHE") or Path(xdg) / "arduinobot")
            root = root.expanduser()
        self.root = Path(root)

    def _path(self, kind: str, key: str) -> Path:
        return self.root / kind / f"{key}.npz"

    def load(self, kind: str, key: str) -> Mapping[str, np.ndarray] | None:
        path = self._path(kind, key)
        try:
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
        except FileNotFoundError:
            return None
        except (OSError, ValueError, zipfile.BadZipFile) as e:
            _log.warning("cache entry %s is unreadable (%s); recomputing", path, e)
            return None

    def store(self, kind: str, key: str, arrays: Mapping[str, np.ndarray]) -> None:
        path = self._path(kind, key)
        tmp = None
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".npz")
            # as Any: mypy would match **arrays against savez's allow_pickle: bool as well
            named: dict[str, Any] = dict(arrays)
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **named)
            os.replace(tmp, path)
            tmp = None
        except OSError as e:
            _log.warning("cannot write the cache entry %s (%s): the next start recomputes it",
                         path, e)
        finally:
            if tmp is not None:
                Path(tmp).unlink(missing_ok=True)
