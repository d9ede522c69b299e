"""The robot a service plans for, loaded here: the twin a plan is replayed on must be the
service's robot, not whatever model this machine ships (issue 27, item 3).

``<prefix>/description`` carries the expanded URDF and the paths of the configuration it
was loaded with; the meshes it names (``package://``) are found in the packages beside
those files, as the service found them. A service on another machine has paths that do
not exist here: then the user must name the model (FILE) themselves.
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from arduinobot.cli.argtypes import UsageError
from arduinobot.description import Description, DescriptionError, load_description
from arduinobot.description.loader import find_package_root
from arduinobot.service.process.disk_cache import DiskCache


def model_of_service(body: Mapping[str, Any]) -> Description:
    """The :class:`Description` of a ``<prefix>/description`` reply ``body``.

    Raises:
        UsageError: its configuration files are not on this machine, or its meshes cannot
            be found from them (the message says to pass the model file).
    """
    cfg: Mapping[str, Any] = body.get("config") or {}
    files = [Path(p) for p in (cfg.get("moveit_package"), cfg.get("srdf"),
                               cfg.get("joint_limits")) if p]
    missing = [str(p) for p in files if not p.exists()]
    if missing:
        raise UsageError(f"the service's model files are not on this machine "
                         f"({', '.join(missing)}): give the model file (FILE, with "
                         "--package-dir) of the robot the service serves")
    roots = {find_package_root(p if p.is_dir() else p.parent) for p in files}
    package_dirs = sorted({str(r.parent) for r in roots if r is not None})
    with tempfile.TemporaryDirectory(prefix="arduinobot-service-model-") as tmp:
        urdf = Path(tmp) / f"{body.get('robot') or 'robot'}.urdf"
        urdf.write_text(str(body["urdf"]), "utf-8")
        opts: dict[str, Any] = {"package_dirs": package_dirs}
        if cfg.get("moveit_package"):
            opts["moveit_config"] = cfg["moveit_package"]
        else:
            opts.update(srdf=cfg.get("srdf"), joint_limits=cfg.get("joint_limits"))
        try:
            return load_description(urdf, **opts)
        except DescriptionError as e:
            raise UsageError(f"cannot load the service's robot here ({e}): give its model "
                             "file (FILE, with --package-dir)") from None


def disk_cache() -> DiskCache:
    """The user's cache folder: a twin's mesh pieces are computed once per machine."""
    return DiskCache()


def progress_printer() -> Callable[[str], None]:
    """Tells the user what a first twin of a new model is building (seconds per mesh),
    on stderr."""
    said: list[bool] = []

    def show(message: str) -> None:
        if not said:
            print("building the MuJoCo twin of this model for the first time (its meshes' "
                  "convex pieces are kept in the cache for the next runs)", file=sys.stderr)
            said.append(True)
        print(f"  {message}", file=sys.stderr, flush=True)
    return show
