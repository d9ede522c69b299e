"""Finding ROS packages and resolving resource URIs without a ROS install.

Mirrors how ROS 2 finds a package's share folder, with the model's own workspace put
where a user expects it. The order, first match wins for a name:

1. the package holding the model file (the nearest folder at or above it with a
   ``package.xml``), for its own name: the xacro you point at is the package its
   ``$(find <own name>)`` and ``package://<own name>/`` mean, whatever else is installed;
2. ``--package-dir`` folders, in the order given;
3. ``ROS_PACKAGE_PATH`` (folders searched for ``package.xml``);
4. ``AMENT_PREFIX_PATH`` (``<prefix>/share/<pkg>``);
5. the model package's siblings, as colcon sees the workspace: the packages under the
   workspace's ``src/`` (the nearest ancestor named ``src``, at most two levels above the
   package), else under the package's parent folder; so the course's xacro finds
   ``$(find arduinobot_controller)`` beside it without any option;
6. last, the arduinobot package shipped with this project: never ahead of a user's.

A package of the model's own name found elsewhere (2-4) is shadowed with a warning naming
both folders (the shipped copy is shadowed silently: that is what it is for).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlparse

from lxml import etree

from arduinobot.description.errors import MeshNotFound, PackageNotFound

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
        origins: package name -> where it was found (``"the model's package"``,
            ``"--package-dir DIR"``, ``"workspace DIR"``, ``"shipped"``, ...).
        warnings: a package of the model's own name found elsewhere too, naming both.
    """

    packages: Mapping[str, Path] = field(default_factory=dict)
    searched: tuple[str, ...] = ()
    origins: Mapping[str, str] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def find(self, name: str, *, file: str | Path | None = None,
             element: str | None = None) -> Path:
        """The folder of package ``name``; raises :class:`PackageNotFound`."""
        try:
            return self.packages[name]
        except KeyError:
            raise PackageNotFound(name, searched=list(self.searched), file=file,
                                  element=element) from None


def find_package_root(path: Path) -> Path | None:
    """The nearest folder at or above ``path`` holding a ``package.xml``."""
    for d in [path, *path.parents]:
        if (d / "package.xml").is_file():
            return d
    return None


# How far above a package its workspace's src/ may sit (src/pkg, src/group/pkg): further
# up, a folder named src is someone's source tree, not this package's workspace.
_SRC_LEVELS = 2


def workspace_folder(package_root: Path) -> tuple[Path, int]:
    """Where the siblings of ``package_root`` live, and how deep to search: the
    workspace's ``src/`` (the nearest ancestor so named, at most two levels up), searched
    as deep as colcon does; else the package's parent, searched two levels deep (it may
    be a home folder)."""
    for d in package_root.parents[:_SRC_LEVELS]:
        if d.name == "src":
            return d, 6
    return package_root.parent, 2


def build_package_index(
    package_dirs: Sequence[str | Path] = (),
    *,
    env: Mapping[str, str] | None = None,
    include_shipped: bool = True,
    model: str | Path | None = None,
) -> PackageIndex:
    """Index the packages visible from the model's package and workspace, explicit
    folders and the environment, in the module's order.

    Args:
        package_dirs: folders that either are a package (hold ``package.xml``) or
            contain packages; searched in order, after the model's own package.
        env: the environment to read ``ROS_PACKAGE_PATH`` and ``AMENT_PREFIX_PATH``
            from (default: ``os.environ``).
        include_shipped: also know the shipped ``arduinobot_description``, at the
            lowest priority, so a user's own copy always wins.
        model: the model file (URDF or xacro): its package wins for its own name and
            its workspace's packages are searched after the environment.
    """
    env = os.environ if env is None else env
    found: dict[str, Path] = {}
    origins: dict[str, str] = {}
    searched: list[str] = []
    shadowed: list[tuple[Path, str]] = []  # other folders of the model package's name
    own = find_package_root(Path(model).expanduser().resolve().parent) if model else None
    own_name = package_name(own) if own is not None else None

    def add(name: str, path: Path, where: str) -> None:
        path = path.resolve()
        if name not in found:
            found[name], origins[name] = path, where
        elif name == own_name and path != found[name] and not where.startswith("shipped"):
            shadowed.append((path, where))

    if own is not None and own_name is not None:
        searched.append(f"the model's package {own}")
        add(own_name, own, "the model's package")
    for raw in package_dirs:
        d = Path(raw).expanduser()
        searched.append(f"--package-dir {d}")
        for pkg in _find_manifests(d):
            add(package_name(pkg), pkg, f"--package-dir {d}")
    for raw in filter(None, env.get("ROS_PACKAGE_PATH", "").split(os.pathsep)):
        searched.append(f"ROS_PACKAGE_PATH {raw}")
        for pkg in _find_manifests(Path(raw)):
            add(package_name(pkg), pkg, f"ROS_PACKAGE_PATH {raw}")
    for raw in filter(None, env.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        share = Path(raw) / "share"
        searched.append(f"AMENT_PREFIX_PATH {share}")
        if share.is_dir():
            for pkg in sorted(p for p in share.iterdir() if p.is_dir()):
                add(pkg.name, pkg, f"AMENT_PREFIX_PATH {share}")
    if own is not None and own.resolve() != SHIPPED_PACKAGE_DIR:
        ws, depth = workspace_folder(own)
        searched.append(f"the model's workspace {ws}")
        for pkg in _find_manifests(ws, max_depth=depth):
            add(package_name(pkg), pkg, f"the model's workspace {ws}")
    if include_shipped:
        searched.append(f"shipped {SHIPPED_PACKAGE_DIR}")
        add(SHIPPED_PACKAGE, SHIPPED_PACKAGE_DIR, "shipped")
    # only add() under own_name fills shadowed, so own_name is set when it is not empty
    warnings = tuple(
        f"package '{own_name}' resolves to {found[own_name]} (the package holding the model); "
        f"the copy in {path} ({where}) is not used"
        for path, where in shadowed if own_name is not None)
    return PackageIndex(packages=found, searched=tuple(searched), origins=origins,
                        warnings=warnings)


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
