"""The two robots of the peer benchmark (bench/peer.py) and the files each side needs.

- ``course``: the course-like workspace (tests/helpers/course_workspace.py): millimetre
  CAD meshes of 2k-54k triangles, a camera on a fixed joint, a separate
  ``arduinobot_moveit`` package with the SRDF and joint_limits.yaml;
- ``course_fingers``: the same workspace with its SRDF's ``disable_collisions`` cut to
  the joint-connected pairs (as a model without an SRDF, or an SRDF that does not
  disable them): the two fingers, and every pair the course's SRDF calls "Never", are
  checked;
- ``shipped``: the arduinobot shipped in src/arduinobot/description/ (``arduinobot serve``'s default).

For each: the arguments of ``arduinobot serve``, the description as the service loads
it, and the plain URDF + SRDF MPlib and the independent re-check (bench/_lib/recheck.py)
read. The URDF is the expanded xacro with every ``package://`` mesh made a path relative
to the URDF's folder, ``scale`` kept: MPlib 0.2.1 prefixes the URDF's folder to every
mesh path, absolute ones too, so an absolute path cannot be used with it; yourdfpy
resolves relative paths the same way. The SRDF is the model's own ``disable_collisions``
plus every pair of links a joint connects (the service never checks those either; read
from the URDF's joints here, not from the planner).
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from arduinobot.description import Description, load_description
from arduinobot.description.loader import read_model_text

ModelName = Literal["course", "course_fingers", "shipped"]


@dataclass(frozen=True)
class PeerModel:
    """One robot as both sides get it.

    Attributes:
        name: ``course``, ``course_fingers`` or ``shipped``.
        description: as ``arduinobot serve`` loads it (same files, same MoveIt config).
        serve_args: the model arguments of ``arduinobot serve`` (empty: its default).
        urdf: the expanded URDF for MPlib and the re-check (relative mesh paths, scale kept).
        srdf: the model's disabled pairs plus the joint-connected ones.
        source: where the model came from (for the report).
    """

    name: ModelName
    description: Description
    serve_args: tuple[str, ...]
    urdf: Path
    srdf: Path
    source: str


def plain_urdf(d: Description, folder: Path) -> Path:
    """The expanded URDF of ``d`` in ``folder``, mesh URIs relative to it; its path."""
    text, _ = read_model_text(d.robot.source, packages=d.packages)
    folder.mkdir(parents=True, exist_ok=True)

    def local(m: re.Match[str]) -> str:
        pkg = d.packages.find(m.group(1))
        return os.path.relpath(Path(pkg).resolve() / m.group(2), folder.resolve())

    text = re.sub(r"package://([^/\"]+)/([^\"]+)", local, text)
    if "package://" in text:
        raise ValueError("a package:// URI is left in the expanded URDF")
    urdf = folder / f"{d.robot.name}.urdf"
    urdf.write_text(text)
    return urdf


def plain_srdf(d: Description, folder: Path) -> Path:
    """An SRDF with the model's ``disable_collisions`` and every joint-connected pair."""
    pairs: dict[frozenset[str], tuple[str, str, str]] = {}
    if d.srdf is not None and d.srdf.source is not None:
        for e in ET.parse(d.srdf.source).getroot().iter("disable_collisions"):
            a, b = e.get("link1", ""), e.get("link2", "")
            pairs[frozenset((a, b))] = (a, b, e.get("reason", ""))
    for j in d.robot.joints.values():
        pairs.setdefault(frozenset((j.parent, j.child)), (j.parent, j.child, "Adjacent"))
    body = "".join(f'  <disable_collisions link1="{a}" link2="{b}" reason="{r}"/>\n'
                   for a, b, r in pairs.values())
    folder.mkdir(parents=True, exist_ok=True)
    srdf = folder / f"{d.robot.name}.srdf"
    srdf.write_text(f'<robot name="{d.robot.name}">\n{body}</robot>\n')
    return srdf


def joints_only_srdf(srdf: Path, joints: list[tuple[str, str]]) -> None:
    """Rewrite ``srdf`` in place: its ``disable_collisions`` only for the pairs a joint
    connects (``joints``: (parent, child) links); everything else kept."""
    tree = ET.parse(srdf)
    root = tree.getroot()
    connected = {frozenset(p) for p in joints}
    for e in list(root.iter("disable_collisions")):
        if frozenset((e.get("link1", ""), e.get("link2", ""))) not in connected:
            root.remove(e)
    tree.write(srdf)


def course_model(folder: Path, *, tri_target: int = 20000, seed: int = 0,
                 fingers: bool = False) -> PeerModel:
    """Generate the course workspace in ``folder`` and prepare it; with ``fingers`` its
    SRDF disables only joint-connected pairs (``course_fingers``)."""
    from tests.helpers.course_workspace import make_course_workspace
    ws = make_course_workspace(folder / "ws", tri_target=tri_target, seed=seed)
    d = load_description(ws.xacro, package_dirs=[ws.src], moveit_config=ws.moveit_pkg)
    if fingers:
        assert d.srdf is not None and d.srdf.source is not None
        joints_only_srdf(Path(d.srdf.source),
                         [(j.parent, j.child) for j in d.robot.joints.values()])
        d = load_description(ws.xacro, package_dirs=[ws.src], moveit_config=ws.moveit_pkg)
    files = folder / "plain"
    return PeerModel("course_fingers" if fingers else "course", d,
                     (str(ws.xacro), "--package-dir", str(ws.src),
                      "--moveit-config", str(ws.moveit_pkg)),
                     plain_urdf(d, files), plain_srdf(d, files),
                     f"course workspace (tri_target {tri_target}, seed {seed})"
                     + ("; SRDF cut to the joint-connected pairs: fingers checked"
                        if fingers else ""))


def shipped_model(folder: Path) -> PeerModel:
    """The shipped arduinobot, as ``arduinobot serve`` loads it by default."""
    d = load_description()
    files = folder / "plain"
    return PeerModel("shipped", d, (), plain_urdf(d, files), plain_srdf(d, files),
                     "shipped arduinobot (serve's default)")


def make_model(name: ModelName, folder: Path) -> PeerModel:
    """``course`` or ``shipped``, with its files under ``folder``."""
    if name == "course":
        return course_model(folder)
    if name == "course_fingers":
        return course_model(folder, fingers=True)
    if name == "shipped":
        return shipped_model(folder)
    raise ValueError(f"unknown model {name!r} (course, course_fingers, shipped)")
