"""Finding ROS packages and resolving resource URIs without a ROS install.

Mirrors how ROS 2 finds a package's share folder: explicit folders first, then
``ROS_PACKAGE_PATH`` (folders searched for ``package.xml``), then ``AMENT_PREFIX_PATH``
(``<prefix>/share/<pkg>``), and last the arduinobot package shipped with this project.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlparse

from lxml import etree

from .errors import MeshNotFound, PackageNotFound

SHIPPED_PACKAGE_DIR = Path(__file__).resolve().parent / "arduinobot_description"
SHIPPED_PACKAGE = "arduinobot_description"

# Folders that never hold packages but can be huge; skipping them keeps a search of a
# workspace fast.
_SKIP_DIRS = {".git", "build", "install", "log", "__pycache__", ".venv", "node_modules"}


def package_name(package_dir: Path) -> str:
    """The package's name as its ``package.xml`` declares it (the folder name if absent)."""
    manifest = package_dir / "package.xml"
    if manifest.is_file():
        try:
            name = etree.parse(str(manifest)).findtext("name")
        except etree.XMLSyntaxError:
            name = None
        if name and name.strip():
            return name.strip()
    return package_dir.name


def _find_manifests(root: Path, *, max_depth: int = 6) -> Iterable[Path]:
    """Package folders under ``root``, not descending into a package (as ROS does)."""
    if not root.is_dir():
        return
    if (root / "package.xml").is_file():
        yield root
        return
    if max_depth == 0:
        return
    try:
        children = sorted(p for p in root.iterdir() if p.is_dir())
    except OSError:
        return
    for child in children:
        if child.name in _SKIP_DIRS or child.name.startswith("."):
            continue
        yield from _find_manifests(child, max_depth=max_depth - 1)


@dataclass(frozen=True)
class PackageIndex:
    """Where each known package lives, and which places were searched.

    Attributes:
        packages: package name -> its share folder.
        searched: the places looked in, in priority order (for error messages).
    """

    packages: Mapping[str, Path] = field(default_factory=dict)
    searched: tuple[str, ...] = ()

    def find(self, name: str, *, file: str | Path | None = None,
             element: str | None = None) -> Path:
        """The folder of package ``name``; raises :class:`PackageNotFound`."""
        try:
            return self.packages[name]
        except KeyError:
            raise PackageNotFound(name, searched=list(self.searched), file=file,
                                  element=element) from None


def build_package_index(
    package_dirs: Sequence[str | Path] = (),
    *,
    env: Mapping[str, str] | None = None,
    include_shipped: bool = True,
) -> PackageIndex:
    """Index the packages visible from explicit folders and the environment.

    Args:
        package_dirs: folders that either are a package (hold ``package.xml``) or
            contain packages; searched first, in order.
        env: the environment to read ``ROS_PACKAGE_PATH`` and ``AMENT_PREFIX_PATH``
            from (default: ``os.environ``).
        include_shipped: also know the shipped ``arduinobot_description``, at the
            lowest priority, so a user's own copy always wins.
    """
    env = os.environ if env is None else env
    found: dict[str, Path] = {}
    searched: list[str] = []

    def add(name: str, path: Path) -> None:
        found.setdefault(name, path.resolve())

    for raw in package_dirs:
        d = Path(raw).expanduser()
        searched.append(f"--package-dir {d}")
        for pkg in _find_manifests(d):
            add(package_name(pkg), pkg)
    for raw in filter(None, env.get("ROS_PACKAGE_PATH", "").split(os.pathsep)):
        searched.append(f"ROS_PACKAGE_PATH {raw}")
        for pkg in _find_manifests(Path(raw)):
            add(package_name(pkg), pkg)
    for raw in filter(None, env.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        share = Path(raw) / "share"
        searched.append(f"AMENT_PREFIX_PATH {share}")
        if share.is_dir():
            for pkg in sorted(p for p in share.iterdir() if p.is_dir()):
                add(pkg.name, pkg)
    if include_shipped:
        searched.append(f"shipped {SHIPPED_PACKAGE_DIR}")
        add(SHIPPED_PACKAGE, SHIPPED_PACKAGE_DIR)
    return PackageIndex(packages=found, searched=tuple(searched))


_PACKAGE_URI = re.compile(r"^package://([^/]+)/(.*)$")


def resolve_uri(
    uri: str,
    *,
    packages: PackageIndex,
    base_dir: Path | None,
    file: str | Path | None = None,
    element: str | None = None,
    must_exist: bool = True,
) -> Path:
    """Turn a resource URI from a URDF into a local path.

    Handles ``package://pkg/rel``, ``file:///abs``, absolute paths and paths relative
    to ``base_dir`` (the folder of the URDF or xacro file).

    Raises:
        PackageNotFound: the package is unknown.
        MeshNotFound: ``must_exist`` and the file is missing.
    """
    m = _PACKAGE_URI.match(uri)
    if m:
        path = packages.find(m.group(1), file=file, element=element) / m.group(2)
    elif uri.startswith("file://"):
        path = Path(unquote(urlparse(uri).path))
    else:
        p = Path(uri)
        if not p.is_absolute():
            if base_dir is None:
                raise MeshNotFound(
                    f"relative path '{uri}' cannot be resolved: the model was not read "
                    "from a file", file=file, element=element,
                    hint="use package:// or an absolute path",
                )
            p = base_dir / p
        path = p
    if must_exist and not path.is_file():
        raise MeshNotFound(f"'{uri}' resolves to {path}, which does not exist",
                           file=file, element=element,
                           hint="check the file name (case matters: .STL vs .stl) and "
                           "the package folder")
    return path
