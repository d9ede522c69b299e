"""Errors raised while loading and checking a robot description.

Every error names the file, the element and the fix, so a user never has to read a
traceback from xacro, lxml or trimesh to learn what is wrong with their model.
"""

from __future__ import annotations

from pathlib import Path


class DescriptionError(Exception):
    """Root of every description error.

    Attributes:
        file: the file at fault, when known.
        element: the element at fault (e.g. ``joint 'joint_2'``), when known.
        hint: how to fix it.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        element: str | None = None,
        hint: str | None = None,
    ) -> None:
        self.message = message
        self.file = str(file) if file is not None else None
        self.element = element
        self.hint = hint
        super().__init__(self._render())

    def at(self, element: str | None) -> DescriptionError:
        """This error, naming ``element`` if it named none (a mesh's file knows its path;
        the caller reading it knows which link element it is)."""
        if element is not None and self.element is None:
            self.element = element
            self.args = (self._render(),)
        return self

    def _render(self) -> str:
        where = []
        if self.file:
            where.append(self.file)
        if self.element:
            where.append(self.element)
        text = f"{': '.join(where)}: {self.message}" if where else self.message
        if self.hint:
            text += f" (fix: {self.hint})"
        return text


class MalformedXml(DescriptionError):
    """The file is not well-formed XML."""


class XacroError(DescriptionError):
    """xacro could not expand the file (bad macro, property or expression)."""


class MissingXacroArgument(XacroError):
    """A ``$(arg name)`` has no value and no default."""

    def __init__(self, name: str, *, file: str | Path | None = None) -> None:
        self.name = name
        super().__init__(
            f"xacro argument '{name}' has no value and no default",
            file=file,
            element=f"$(arg {name})",
            hint=f"pass it with --arg {name}=VALUE (or args={{'{name}': ...}}), "
            f"or declare <xacro:arg name=\"{name}\" default=\"...\"/>",
        )


class PackageNotFound(DescriptionError):
    """A ``package://`` URI or ``$(find pkg)`` names a package we cannot locate."""

    def __init__(self, package: str, *, searched: list[str], file: str | Path | None = None,
                 element: str | None = None) -> None:
        self.package = package
        self.searched = searched
        where = ", ".join(searched) if searched else "nothing (no package folders given)"
        super().__init__(
            f"package '{package}' not found; searched {where}",
            file=file,
            element=element,
            hint=f"pass --package-dir DIR where DIR/package.xml names '{package}', "
            "or add its parent folder to ROS_PACKAGE_PATH, or its install prefix to "
            "AMENT_PREFIX_PATH",
        )


class MeshNotFound(DescriptionError):
    """A mesh URI resolves to a file that does not exist."""


class MeshLoadError(DescriptionError):
    """A mesh file exists but cannot be read as a mesh."""


class InvalidModel(DescriptionError):
    """The URDF is well-formed XML but not a valid robot (bad tree, bad values)."""


class SrdfError(DescriptionError):
    """The SRDF is malformed or refers to links, joints or groups the URDF lacks."""
