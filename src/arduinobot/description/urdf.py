"""Parsing URDF text into a :class:`~arduinobot.description.model.Robot`.

Parsing is lenient and collects every problem it meets (so ``arduinobot check`` can
list them all); :func:`parse_urdf` then raises the first one unless asked not to.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from arduinobot.description.errors import DescriptionError, InvalidModel, MalformedXml
from arduinobot.description.geometry import Geometry, MeshFile
from arduinobot.description.model import (
    Inertial,
    Joint,
    Limit,
    Link,
    Mimic,
    Origin,
    Robot,
    Shape,
)
from arduinobot.description.packages import PackageIndex, resolve_uri
from arduinobot.scene.shapes import Box, Cylinder, Sphere

_SHAPES = ("mesh", "box", "sphere", "cylinder")
_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


@dataclass
class ParseReport:
    """What parsing found: the robot (when its structure allowed one) and every problem."""

    robot: Robot | None = None
    problems: list[DescriptionError] = field(default_factory=list)
    warnings: list[DescriptionError] = field(default_factory=list)


class _Ctx:
    def __init__(self, source: Path | None, packages: PackageIndex) -> None:
        self.source = source
        self.packages = packages
        self.problems: list[DescriptionError] = []
        self.warnings: list[DescriptionError] = []

    def warn(self, message: str, element: str, hint: str | None = None) -> None:
        self.warnings.append(InvalidModel(message, file=self.source, element=element,
                                          hint=hint))

    def fail(self, message: str, element: str, hint: str | None = None) -> None:
        self.problems.append(InvalidModel(message, file=self.source, element=element, hint=hint))

    def vec3(self, el: etree._Element | None, attr: str, default: tuple[float, float, float],
             where: str) -> tuple[float, float, float]:
        if el is None or el.get(attr) is None:
            return default
        raw = el.get(attr, "")
        try:
            vals = tuple(float(v) for v in raw.split())
        except ValueError:
            vals = ()
        if len(vals) != 3:
            self.fail(f"{attr}=\"{raw}\" must be 3 numbers", where,
                      hint="write 3 space-separated numbers")
            return default
        return vals[0], vals[1], vals[2]

    def number(self, el: etree._Element | None, attr: str, where: str,
               default: float | None = None) -> float | None:
        if el is None or el.get(attr) is None:
            return default
        raw = el.get(attr, "")
        try:
            return float(raw)
        except ValueError:
            self.fail(f"{attr}=\"{raw}\" is not a number", where)
            return default


def _origin(ctx: _Ctx, el: etree._Element | None, where: str) -> Origin:
    if el is None:
        return Origin()
    return Origin(xyz=ctx.vec3(el, "xyz", (0.0, 0.0, 0.0), where),
                  rpy=ctx.vec3(el, "rpy", (0.0, 0.0, 0.0), where))


def _geometry(ctx: _Ctx, el: etree._Element | None, where: str) -> Geometry | None:
    kids = [] if el is None else [c for c in el if isinstance(c.tag, str)]
    shapes = [c for c in kids if c.tag in _SHAPES]
    for c in kids:
        if c.tag not in _SHAPES:
            # e.g. a <material> written inside <geometry>: URDF parsers read the shape
            # and ignore the rest, so do we, but say so
            ctx.warn(f"<{c.tag}> inside <geometry> is ignored", where,
                     hint=f"move <{c.tag}> out of <geometry> (into <visual>)")
    if not kids or (not shapes and all(c.tag == "material" for c in kids)):
        ctx.fail("has no <geometry> shape", where, hint="add <geometry> with a mesh, box, "
                 "cylinder or sphere")
        return None
    g = shapes[0] if shapes else kids[0]
    tag = g.tag
    if tag == "mesh":
        uri = g.get("filename")
        if not uri:
            ctx.fail("<mesh> has no filename", where)
            return None
        path = None
        try:
            path = resolve_uri(uri, packages=ctx.packages,
                               base_dir=ctx.source.parent if ctx.source else None,
                               file=ctx.source, element=where)
        except DescriptionError as e:
            ctx.problems.append(e)
        scale = ctx.vec3(g, "scale", (1.0, 1.0, 1.0), where)
        return MeshFile(uri=uri, path=path, scale=scale)
    # the scene's shapes, built as written (unchecked: a zero size is check's to report)
    if tag == "box":
        return Box(size=ctx.vec3(g, "size", (0.0, 0.0, 0.0), where))
    if tag == "sphere":
        return Sphere(radius=ctx.number(g, "radius", where, 0.0) or 0.0)
    if tag == "cylinder":
        return Cylinder(radius=ctx.number(g, "radius", where, 0.0) or 0.0,
                        length=ctx.number(g, "length", where, 0.0) or 0.0)
    ctx.fail(f"unknown geometry <{tag}>", where, hint="use mesh, box, cylinder or sphere")
    return None


def _shapes(ctx: _Ctx, link_el: etree._Element, tag: str, link: str) -> tuple[Shape, ...]:
    out = []
    for i, el in enumerate(link_el.findall(tag)):
        where = f"link '{link}' <{tag}> #{i + 1}"
        geom = _geometry(ctx, el.find("geometry"), where)
        if geom is not None:
            out.append(Shape(_origin(ctx, el.find("origin"), where), geom, el.get("name")))
    return tuple(out)


def _inertial(ctx: _Ctx, el: etree._Element | None, link: str) -> Inertial | None:
    if el is None:
        return None
    where = f"link '{link}' <inertial>"
    mass_el = el.find("mass")
    if mass_el is None or mass_el.get("value") is None:
        ctx.fail("has no <mass value=...>", where)
        return None
    mass = ctx.number(mass_el, "value", where, 0.0) or 0.0
    inertia = el.find("inertia")
    if inertia is None:
        ctx.fail("has no <inertia>", where, hint="add <inertia ixx= ixy= ixz= iyy= iyz= izz=/>")
        return None
    vals = {k: ctx.number(inertia, k, where, 0.0) or 0.0
            for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    return Inertial(mass=mass, origin=_origin(ctx, el.find("origin"), where), **vals)


def _joint(ctx: _Ctx, el: etree._Element) -> Joint | None:
    name = el.get("name")
    if not name:
        ctx.fail("a <joint> has no name", f"line {el.sourceline}")
        return None
    where = f"joint '{name}'"
    jtype = el.get("type", "")
    if jtype not in _JOINT_TYPES:
        ctx.fail(f"type=\"{jtype}\" is not a URDF joint type", where,
                 hint="use one of " + ", ".join(_JOINT_TYPES))
        return None
    parent_el, child_el = el.find("parent"), el.find("child")
    parent = parent_el.get("link") if parent_el is not None else None
    child = child_el.get("link") if child_el is not None else None
    if not parent or not child:
        ctx.fail("needs <parent link=...> and <child link=...>", where)
        return None
    axis = ctx.vec3(el.find("axis"), "xyz", (1.0, 0.0, 0.0), where)
    limit = None
    lim_el = el.find("limit")
    if lim_el is not None:
        limit = Limit(lower=ctx.number(lim_el, "lower", where, 0.0 if jtype != "continuous" else None),
                      upper=ctx.number(lim_el, "upper", where, 0.0 if jtype != "continuous" else None),
                      effort=ctx.number(lim_el, "effort", where, 0.0) or 0.0,
                      velocity=ctx.number(lim_el, "velocity", where, 0.0) or 0.0)
        if jtype == "continuous":
            limit = Limit(None, None, limit.effort, limit.velocity)
    elif jtype in ("revolute", "prismatic"):
        ctx.fail(f"a {jtype} joint needs <limit lower= upper= effort= velocity=>", where)
    mimic = None
    mim_el = el.find("mimic")
    if mim_el is not None:
        mimic = Mimic(joint=mim_el.get("joint", ""),
                      multiplier=ctx.number(mim_el, "multiplier", where, 1.0) or 0.0,
                      offset=ctx.number(mim_el, "offset", where, 0.0) or 0.0)
    return Joint(name=name, type=jtype, parent=parent, child=child,
                 origin=_origin(ctx, el.find("origin"), where), axis=axis,
                 limit=limit, mimic=mimic)


def structure_problems(links: dict[str, Link], joints: dict[str, Joint],
                       source: Path | None) -> list[DescriptionError]:
    """What ``check_urdf`` checks: names resolve, one root, a tree without cycles."""
    probs: list[DescriptionError] = []

    def fail(msg: str, element: str, hint: str | None = None) -> None:
        probs.append(InvalidModel(msg, file=source, element=element, hint=hint))

    if not links:
        fail("the robot has no links", "<robot>")
        return probs
    parent_of: dict[str, str] = {}
    for j in joints.values():
        for role, link in (("parent", j.parent), ("child", j.child)):
            if link not in links:
                fail(f"{role} link '{link}' does not exist", f"joint '{j.name}'",
                     hint=f"declare <link name=\"{link}\"/> or fix the name")
        if j.child in parent_of:
            fail(f"link '{j.child}' already has parent joint '{parent_of[j.child]}'",
                 f"joint '{j.name}'", hint="a link has exactly one parent joint in a tree")
        parent_of.setdefault(j.child, j.name)
    roots = [n for n in links if n not in {j.child for j in joints.values()}]
    if not roots:
        fail("no root link: every link is some joint's child, so the joints form a cycle",
             "<robot>", hint="remove the joint that closes the loop")
    elif len(roots) > 1:
        fail(f"{len(roots)} root links ({', '.join(roots)}); a robot is one tree",
             "<robot>", hint="connect them with joints")
    # A link reachable from no root sits on a cycle.
    child_joints: dict[str, list[str]] = {}
    for j in joints.values():
        child_joints.setdefault(j.parent, []).append(j.child)
    seen: set[str] = set()
    stack = list(roots)
    while stack:
        link = stack.pop()
        if link in seen:
            continue
        seen.add(link)
        stack.extend(child_joints.get(link, []))
    on_cycle = [n for n in links if n not in seen]
    if roots and on_cycle:
        fail(f"links {', '.join(on_cycle)} form a cycle unreachable from the root",
             "<robot>", hint="a URDF is a tree; remove the joint that closes the loop")
    return probs


def joint_problems(joints: dict[str, Joint], source: Path | None) -> list[DescriptionError]:
    """Per-joint problems that leave the tree intact: mimic targets, zero axes."""
    probs: list[DescriptionError] = []

    def fail(msg: str, element: str, hint: str | None = None) -> None:
        probs.append(InvalidModel(msg, file=source, element=element, hint=hint))

    for j in joints.values():
        if j.mimic is not None:
            if j.mimic.joint not in joints:
                fail(f"mimics joint '{j.mimic.joint}', which does not exist", f"joint '{j.name}'")
            elif joints[j.mimic.joint].mimic is not None:
                fail(f"mimics '{j.mimic.joint}', itself a mimic", f"joint '{j.name}'",
                     hint="mimic the leader joint directly")
        if j.movable and j.type != "floating" and sum(a * a for a in j.axis) < 1e-12:
            fail("axis is zero", f"joint '{j.name}'", hint="give a non-zero <axis xyz=.../>")
    return probs


def parse_urdf(
    text: str,
    *,
    packages: PackageIndex,
    source: Path | None = None,
    strict: bool = True,
) -> ParseReport:
    """Parse URDF text.

    Args:
        text: the URDF (already expanded if it was xacro).
        packages: how ``package://`` URIs resolve.
        source: the file it came from (relative URIs resolve against its folder).
        strict: raise the first problem instead of returning it in the report.

    Raises:
        MalformedXml: not well-formed XML, or no ``<robot>`` root.
        DescriptionError: (strict only) the first problem found.
    """
    try:
        root = etree.fromstring(text.encode("utf-8"),
                                parser=etree.XMLParser(remove_comments=True))
    except etree.XMLSyntaxError as e:
        raise MalformedXml(f"not well-formed XML: {e}", file=source,
                           hint="fix the XML syntax at that line") from e
    if root.tag != "robot":
        raise MalformedXml(f"the root element is <{root.tag}>, not <robot>", file=source)
    ctx = _Ctx(source, packages)
    links: dict[str, Link] = {}
    for el in root.findall("link"):
        name = el.get("name")
        if not name:
            ctx.fail("a <link> has no name", f"line {el.sourceline}")
            continue
        if name in links:
            ctx.fail("is declared twice", f"link '{name}'")
            continue
        links[name] = Link(name=name, inertial=_inertial(ctx, el.find("inertial"), name),
                           visuals=_shapes(ctx, el, "visual", name),
                           collisions=_shapes(ctx, el, "collision", name))
    joints: dict[str, Joint] = {}
    for el in root.findall("joint"):
        j = _joint(ctx, el)
        if j is None:
            continue
        if j.name in joints:
            ctx.fail("is declared twice", f"joint '{j.name}'")
            continue
        joints[j.name] = j
    problems = ctx.problems
    structural = structure_problems(links, joints, source)
    problems.extend(structural)
    problems.extend(joint_problems(joints, source))
    if strict and problems:
        raise problems[0]
    robot = None
    if not structural:
        robot = Robot(name=root.get("name", ""), links=links, joints=joints, urdf=text,
                      source=source, package_dirs=dict(packages.packages))
    return ParseReport(robot=robot, problems=problems, warnings=ctx.warnings)
