"""The SRDF: planning groups, end effectors, named states and disabled collision pairs.

Read and written in MoveIt's format, so a MoveIt user's file works here and ours works
in MoveIt.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from .errors import SrdfError
from .model import Robot


@dataclass(frozen=True)
class Group:
    """A planning group: its joints in order (from ``<joint>`` and ``<chain>`` entries)."""

    name: str
    joints: tuple[str, ...]


@dataclass(frozen=True)
class EndEffector:
    name: str
    parent_link: str
    group: str
    parent_group: str | None = None


@dataclass(frozen=True)
class GroupState:
    """A named state such as ``home``: joint values [rad] for one group."""

    name: str
    group: str
    values: dict[str, float]


@dataclass(frozen=True)
class DisabledCollision:
    """A link pair the collision checker skips, and why (MoveIt's reasons:
    ``Adjacent``, ``Never``, ``Always``, ``Default``, ``User``)."""

    link1: str
    link2: str
    reason: str


@dataclass(frozen=True)
class Srdf:
    robot_name: str
    groups: dict[str, Group]
    end_effectors: tuple[EndEffector, ...]
    group_states: dict[str, GroupState]
    disabled_collisions: tuple[DisabledCollision, ...]
    source: Path | None = None

    def disabled_pairs(self) -> frozenset[frozenset[str]]:
        return frozenset(frozenset((d.link1, d.link2)) for d in self.disabled_collisions)

    def named_state(self, name: str) -> GroupState:
        try:
            return self.group_states[name]
        except KeyError:
            known = ", ".join(sorted(self.group_states)) or "none"
            raise SrdfError(f"no named state '{name}' (known: {known})", file=self.source,
                            element=f"group_state '{name}'") from None


def _chain_joints(robot: Robot, base: str, tip: str, where: str, source: Path | None) -> list[str]:
    path = robot.link_path(tip)
    names = [j.child for j in path]
    if base != robot.root and base not in names:
        raise SrdfError(f"chain base '{base}' is not an ancestor of tip '{tip}'", file=source,
                        element=where)
    start = 0 if base == robot.root else names.index(base) + 1
    return [j.name for j in path[start:]]


def parse_srdf(text: str, robot: Robot, *, source: Path | None = None) -> Srdf:
    """Parse SRDF text and check that every name in it exists in ``robot``.

    Raises:
        SrdfError: malformed XML, or a name the URDF lacks.
    """
    try:
        root = etree.fromstring(text.encode("utf-8"))
    except etree.XMLSyntaxError as e:
        raise SrdfError(f"not well-formed XML: {e}", file=source) from e

    def need_link(name: str | None, where: str) -> str:
        if not name or name not in robot.links:
            raise SrdfError(f"link '{name}' is not in the URDF", file=source, element=where)
        return name

    def need_joint(name: str | None, where: str) -> str:
        if not name or name not in robot.joints:
            raise SrdfError(f"joint '{name}' is not in the URDF", file=source, element=where)
        return name

    groups: dict[str, Group] = {}
    for g in root.findall("group"):
        name = g.get("name", "")
        where = f"group '{name}'"
        joints: list[str] = []
        for child in g:
            if child.tag == "joint":
                joints.append(need_joint(child.get("name"), where))
            elif child.tag == "chain":
                joints.extend(_chain_joints(robot, need_link(child.get("base_link"), where),
                                            need_link(child.get("tip_link"), where), where, source))
            elif child.tag == "group":
                sub = groups.get(child.get("name", ""))
                if sub is None:
                    raise SrdfError(f"subgroup '{child.get('name')}' must be declared first",
                                    file=source, element=where)
                joints.extend(sub.joints)
        movable = tuple(j for j in dict.fromkeys(joints) if robot.joints[j].movable)
        groups[name] = Group(name, movable)
    effs = []
    for e in root.findall("end_effector"):
        where = f"end_effector '{e.get('name')}'"
        group = e.get("group", "")
        if group not in groups:
            raise SrdfError(f"group '{group}' is not declared", file=source, element=where)
        effs.append(EndEffector(e.get("name", ""), need_link(e.get("parent_link"), where), group,
                                e.get("parent_group")))
    states: dict[str, GroupState] = {}
    for s in root.findall("group_state"):
        name, group = s.get("name", ""), s.get("group", "")
        where = f"group_state '{name}'"
        if group not in groups:
            raise SrdfError(f"group '{group}' is not declared", file=source, element=where)
        values: dict[str, float] = {}
        for j in s.findall("joint"):
            jn = need_joint(j.get("name"), where)
            try:
                values[jn] = float(j.get("value", ""))
            except ValueError:
                raise SrdfError(f"joint '{jn}' value=\"{j.get('value')}\" is not a number",
                                file=source, element=where) from None
        states[name] = GroupState(name, group, values)
    disabled = []
    for d in root.findall("disable_collisions"):
        where = f"disable_collisions {d.get('link1')}/{d.get('link2')}"
        disabled.append(DisabledCollision(need_link(d.get("link1"), where),
                                          need_link(d.get("link2"), where),
                                          d.get("reason", "User")))
    return Srdf(robot_name=root.get("name", ""), groups=groups, end_effectors=tuple(effs),
                group_states=states, disabled_collisions=tuple(disabled), source=source)


def replace_disabled_collisions(text: str, pairs: Iterable[DisabledCollision]) -> str:
    """Return SRDF ``text`` with its ``<disable_collisions>`` replaced by ``pairs``.

    Everything else in the file, comments included, is kept.
    """
    root = etree.fromstring(text.encode("utf-8"))
    for d in root.findall("disable_collisions"):
        root.remove(d)
    tail_anchor = root[-1] if len(root) else None
    if tail_anchor is not None:
        tail_anchor.tail = "\n    "
    for p in pairs:
        el = etree.SubElement(root, "disable_collisions", link1=p.link1, link2=p.link2,
                              reason=p.reason)
        el.tail = "\n    "
    if len(root):
        root[-1].tail = "\n"
    # Serialise the whole document so comments before <robot> survive too; lxml drops
    # the line breaks between top-level nodes, so put one after each.
    body = etree.tostring(root.getroottree(), encoding="unicode")
    cut = body.index("<" + root.tag)
    body = body[:cut].replace("-->", "-->\n") + body[cut:]
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + body + "\n"
