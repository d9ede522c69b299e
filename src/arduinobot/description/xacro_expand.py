"""In-process xacro expansion with ``$(find pkg)`` answered by our package index.

The xacro package asks ``ament_index_python`` for ``$(find pkg)``; we have no ROS, so
its lookup is redirected to a :class:`PackageIndex` for the duration of one expansion.
xacro keeps module-level state, so expansions are serialised by a lock.
"""

from __future__ import annotations

import logging
import re
import threading
import xml.parsers.expat
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import xacro
from lxml import etree
from xacro import substitution_args

from arduinobot.description.errors import (
    MalformedXml,
    MissingXacroArgument,
    PackageNotFound,
    XacroError,
)
from arduinobot.description.packages import PackageIndex

_log = logging.getLogger(__name__)
_lock = threading.Lock()


def is_xacro(path: Path, text: str | None = None) -> bool:
    """Whether ``path`` needs xacro: by its ending, or a xacro namespace inside."""
    if path.name.endswith(".xacro"):
        return True
    if text is None:
        text = path.read_text(encoding="utf-8", errors="replace")
    return "http://www.ros.org/wiki/xacro" in text or "<xacro:" in text


@dataclass(frozen=True)
class XacroExpansion:
    """A xacro file expanded: the URDF ``text``, the arguments the file and its includes
    declare (``<xacro:arg name=...>``), and ``warnings``: xacro's own (which it would
    print), then each argument given that none of them declares (xacro ignores it without
    a word)."""

    text: str
    declared_args: tuple[str, ...]
    warnings: tuple[str, ...] = ()


def expand_xacro(
    path: str | Path,
    *,
    args: Mapping[str, str] | None = None,
    packages: PackageIndex,
) -> str:
    """Expand a xacro file to URDF text (see :func:`expand_xacro_report`)."""
    return expand_xacro_report(path, args=args, packages=packages).text


def expand_xacro_report(
    path: str | Path,
    *,
    args: Mapping[str, str] | None = None,
    packages: PackageIndex,
) -> XacroExpansion:
    """Expand a xacro file to URDF text, and say which given arguments it ignores.

    Args:
        path: the ``.xacro`` file.
        args: values for ``$(arg name)``.
        packages: where ``$(find pkg)`` looks.

    Raises:
        MalformedXml: the file (or an include) is not well-formed XML.
        MissingXacroArgument: an argument has no value and no default.
        PackageNotFound: ``$(find pkg)`` names an unknown package.
        XacroError: any other xacro failure, with xacro's own message.
    """
    path = Path(path)
    if not path.is_file():
        raise XacroError("file does not exist", file=path,
                         hint="check the path, or omit FILE for the shipped model")

    missing: list[PackageNotFound] = []

    def find(pkg: str) -> str:
        try:
            return str(packages.find(pkg, file=path, element=f"$(find {pkg})"))
        except PackageNotFound as e:
            # xacro wraps whatever its lookup raises; keep ours to re-raise it intact.
            missing.append(e)
            raise

    mappings = {str(k): str(v) for k, v in (args or {}).items()}
    said: list[str] = []

    def warning(*parts: object, **_: object) -> None:
        # xacro prints its warnings ('redefining global symbol: pi') to stderr itself, in
        # every command and every worker: kept as the expansion's warnings instead, which
        # the loader logs and check lists, naming the file being processed
        where = xacro.filestack[-1] if xacro.filestack else path
        said.append(f"xacro: {' '.join(map(str, parts))} (in {where})")
    with _lock:
        saved = substitution_args._eval_find, substitution_args._eval_dict.get("find")
        substitution_args._eval_find = find
        substitution_args._eval_dict["find"] = find
        printing = xacro.warning, xacro.print_location
        xacro.warning, xacro.print_location = warning, lambda: None
        xacro.all_includes.clear()  # xacro appends every file it includes here
        try:
            doc = xacro.process_file(str(path), mappings=mappings, verbosity=0)
            files = [path, *(Path(f) for f in dict.fromkeys(xacro.all_includes))]
        except xml.parsers.expat.ExpatError as e:
            raise MalformedXml(f"not well-formed XML: {e}", file=_current_file(path),
                               hint="fix the XML syntax at that line") from e
        except substitution_args.ArgException as e:
            raise MissingXacroArgument(str(e.args[0]) if e.args else "?",
                                       file=path) from e
        except Exception as e:  # xacro raises bare XacroException and others
            if missing:
                raise missing[0] from e
            raise _translate(e, path) from e
        finally:
            substitution_args._eval_find = saved[0]
            substitution_args._eval_dict["find"] = saved[1]
            xacro.warning, xacro.print_location = printing
            xacro.init_stacks(None)
    text = doc.toprettyxml(indent="  ")
    _log.debug("expanded %s (%d bytes)", path, len(text))
    declared = declared_args(files)
    unknown = [n for n in mappings if n not in declared]
    listed = ", ".join(declared) if declared else "none"
    warnings = tuple(dict.fromkeys(said)) + tuple(
        f"--arg {n}: {path.name} declares no such xacro argument, so it is ignored "
        f"(declared: {listed})" for n in unknown)
    return XacroExpansion(text=text, declared_args=declared, warnings=warnings)


_XACRO_ARG = "{http://www.ros.org/wiki/xacro}arg"


def declared_args(files: list[Path]) -> tuple[str, ...]:
    """The names of the ``<xacro:arg>`` elements in ``files``, in order of appearance
    (an argument declared inside a conditional is declared all the same)."""
    names: dict[str, None] = {}
    for f in files:
        try:
            root = etree.parse(str(f)).getroot()
        except (OSError, etree.XMLSyntaxError):  # xacro has read it: a yaml, a moved file
            continue
        for e in root.iter(_XACRO_ARG):
            name = e.get("name")
            if name:
                names.setdefault(name, None)
    return tuple(names)


def _current_file(default: Path) -> str:
    # xacro tracks the file being read on its stack; an include's error belongs there.
    stack = [f for f in (xacro.filestack or []) if f]
    return str(stack[-1]) if stack else str(default)


_UNDEFINED_ARG = re.compile(r"Undefined substitution argument (\S+)")


def _translate(e: Exception, path: Path) -> XacroError:
    msg = str(e) or repr(e)
    m = _UNDEFINED_ARG.search(msg)
    if m:
        return MissingXacroArgument(m.group(1), file=path)
    if isinstance(e, xacro.XacroException):
        macro = getattr(e, "macro", None)
        element = f"macro '{macro.body.getAttribute('name')}'" if macro is not None else None
        return XacroError(f"xacro: {msg}", file=_current_file(path), element=element,
                          hint="check the property, macro or expression named above")
    return XacroError(f"xacro failed: {type(e).__name__}: {msg}", file=_current_file(path))
