"""The SRDF: planning groups, end effectors, named states and disabled collision pairs.

Read and written in MoveIt's format, so a MoveIt user's file works here and ours works
in MoveIt.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from arduinobot.description.errors import SrdfError
from arduinobot.description.model import Robot


@dataclass(frozen=True)
class Group:
    """A planning group.

    Attributes:
        joints: its movable joints in chain order (from ``<joint>``, ``<chain>``,
            ``<link>`` and subgroup entries); fixed and virtual joints are left out.
        links: every link the group's entries name or imply, in order.
        tip_link: the deepest link of the group (its chain's tip), or None for a group
            without links.
    """

    name: str
    joints: tuple[str, ...]
    links: tuple[str, ...] = ()
    tip_link: str | None = None


@dataclass(frozen=True)
class EndEffector:
    name: str
    parent_link: str
    group: str
    parent_group: str | None = None


@dataclass(frozen=True)
class GroupState:
    """A named state such as ``home``: joint values [rad] for one group. Names are unique
    per group, not per file: MoveIt's setup assistant writes a ``home`` for each group."""

    name: str
    group: str
    values: dict[str, float]


@dataclass(frozen=True)
class DisabledCollision:
    """A link pair the collision checker skips, and why (MoveIt's reasons:
    ``Adjacent``, ``Never``, ``Always``, ``Default``, ``User``; ours add
    ``Never-proven`` and ``Never-sampled``)."""

    link1: str
    link2: str
    reason: str


@dataclass(frozen=True)
class Srdf:
    """A parsed SRDF.

    Attributes:
        states: every ``<group_state>``, in file order.
        warnings: what was skipped and why (e.g. disabled pairs naming links the URDF
            lacks, written before the model changed).
    """

    robot_name: str
    groups: dict[str, Group]
    end_effectors: tuple[EndEffector, ...]
    states: tuple[GroupState, ...]
    disabled_collisions: tuple[DisabledCollision, ...]
    source: Path | None = None
    warnings: tuple[str, ...] = ()

    def disabled_pairs(self) -> frozenset[frozenset[str]]:
        return frozenset(frozenset((d.link1, d.link2)) for d in self.disabled_collisions)

    def state_names(self, group: str | None = None) -> tuple[str, ...]:
        """Names of the named states (of ``group`` only, if given), without repeats."""
        return tuple(dict.fromkeys(s.name for s in self.states
                                   if group is None or s.group == group))

    def labelled_states(self) -> dict[str, GroupState]:
        """Every state under a unique label: its name, or ``group/name`` where several
        groups use the name (for menus and listings)."""
        counts: dict[str, int] = {}
        for s in self.states:
            counts[s.name] = counts.get(s.name, 0) + 1
        return {(s.name if counts[s.name] == 1 else f"{s.group}/{s.name}"): s
                for s in self.states}

    def named_state(self, name: str, group: str | None = None) -> GroupState:
        """The state ``name`` of ``group``; without a group the name must be unique.

        Raises:
            SrdfError: no such state (naming the known ones), or a name several groups
                define and no group to choose (naming those groups).
        """
        found = [s for s in self.states if s.name == name]
        where = f"group_state '{name}'"
        if group is not None:
            mine = [s for s in found if s.group == group]
            if mine:
                return mine[0]
            others = sorted({s.group for s in found})
            hint = (f"'{name}' is defined for group {', '.join(others)}: set group to it"
                    if others else None)
            known = ", ".join(self.state_names(group)) or "none"
            raise SrdfError(f"group '{group}' has no named state '{name}' (its states: "
                            f"{known})", file=self.source, element=where, hint=hint)
        if not found:
            known = ", ".join(self.state_names()) or "none"
            raise SrdfError(f"no named state '{name}' (known: {known})", file=self.source,
                            element=where)
        groups = sorted({s.group for s in found})
        if len(groups) > 1:
            raise SrdfError(f"named state '{name}' is ambiguous: groups {', '.join(groups)} "
                            "each define it", file=self.source, element=where,
                            hint=f"set group to one of {', '.join(groups)}")
        return found[0]

    def default_group(self) -> str | None:
        """The group a request without one plans for: ``arm`` if declared (the
        arduinobot's and most setup assistant configs' name), else the first declared
        group that has movable joints."""
        if "arm" in self.groups and self.groups["arm"].joints:
            return "arm"
        return next((g.name for g in self.groups.values() if g.joints), None)

    def tip_link(self, group: str) -> str | None:
        """The group's tool link: the parent link of an end effector attached to it,
        else the tip of its chain."""
        for e in self.end_effectors:
            if e.parent_group == group:
                return e.parent_link
        g = self.groups.get(group)
        return g.tip_link if g is not None else None


def _chain_joints(robot: Robot, base: str, tip: str, where: str, source: Path | None) -> list[str]:
    path = robot.link_path(tip)
    names = [j.child for j in path]
    if base != robot.root and base not in names:
        raise SrdfError(f"chain base '{base}' is not an ancestor of tip '{tip}'", file=source,
                        element=where)
    start = 0 if base == robot.root else names.index(base) + 1
    return [j.name for j in path[start:]]


# need_link / need_joint: (name or None, where) -> the name, or SrdfError if the URDF lacks it
_Need = Callable[[str | None, str], str]


def _group(robot: Robot, el: etree._Element, raw: dict[str, etree._Element],
           done: dict[str, Group], virtual: set[str], source: Path | None,
           need_link: _Need, need_joint: _Need, visiting: tuple[str, ...] = ()) -> Group:
    name = el.get("name", "")
    if name in done:
        return done[name]
    where = f"group '{name}'"
    if name in visiting:
        raise SrdfError(f"subgroups form a cycle: {' -> '.join((*visiting, name))}",
                        file=source, element=where)
    joints: list[str] = []
    links: list[str] = []
    for child in el:
        if not isinstance(child.tag, str):
            continue
        if child.tag == "joint":
            jn = child.get("name")
            if jn in virtual and jn not in robot.joints:
                continue  # an SRDF virtual joint with no URDF counterpart
            j = robot.joints[need_joint(jn, where)]
            joints.append(j.name)
            links.append(j.child)
        elif child.tag == "chain":
            names = _chain_joints(robot, need_link(child.get("base_link"), where),
                                  need_link(child.get("tip_link"), where), where, source)
            joints.extend(names)
            links.extend(robot.joints[n].child for n in names)
        elif child.tag == "link":
            link = need_link(child.get("name"), where)
            links.append(link)
            parent = robot.parent_joint.get(link)
            if parent is not None:
                joints.append(parent.name)
        elif child.tag == "group":
            sub_el = raw.get(child.get("name", ""))
            if sub_el is None:
                raise SrdfError(f"subgroup '{child.get('name')}' is not declared",
                                file=source, element=where)
            sub = _group(robot, sub_el, raw, done, virtual, source, need_link, need_joint,
                         (*visiting, name))
            joints.extend(sub.joints)
            links.extend(sub.links)
    links = list(dict.fromkeys(links))
    tip = max(links, key=lambda x: len(robot.link_path(x)), default=None)
    movable = tuple(j for j in dict.fromkeys(joints) if robot.joints[j].movable)
    done[name] = Group(name, movable, tuple(links), tip)
    return done[name]


def parse_srdf(text: str, robot: Robot, *, source: Path | None = None) -> Srdf:
    """Parse SRDF text and check that every name in it exists in ``robot``.

    Disabled pairs naming a link the URDF lacks are skipped with a warning (an SRDF
    written before a link was renamed or removed); everything else must resolve.

    Raises:
        SrdfError: malformed XML, or a name the URDF lacks.
    """
    try:
        root = etree.fromstring(text.encode("utf-8"),
                                parser=etree.XMLParser(remove_comments=True))
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

    virtual = {v.get("name", "") for v in root.findall("virtual_joint")}
    raw = {g.get("name", ""): g for g in root.findall("group")}
    done: dict[str, Group] = {}
    for g in raw.values():
        _group(robot, g, raw, done, virtual, source, need_link, need_joint)
    groups = {name: done[name] for name in raw}
    effs = []
    for eff in root.findall("end_effector"):
        where = f"end_effector '{eff.get('name')}'"
        group = eff.get("group", "")
        if group not in groups:
            raise SrdfError(f"group '{group}' is not declared", file=source, element=where)
        effs.append(EndEffector(eff.get("name", ""), need_link(eff.get("parent_link"), where),
                                group, eff.get("parent_group")))
    states: list[GroupState] = []
    seen: set[tuple[str, str]] = set()
    warnings: list[str] = []
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
        if (group, name) in seen:
            warnings.append(f"group_state '{name}' of group '{group}' is declared twice; "
                            "the first is used")
            continue
        seen.add((group, name))
        states.append(GroupState(name, group, values))
    disabled = []
    for d in root.findall("disable_collisions"):
        a, b = d.get("link1"), d.get("link2")
        missing = [x for x in (a, b) if not x or x not in robot.links]
        if missing:
            warnings.append(f"disable_collisions {a}/{b}: link {', '.join(map(repr, missing))} "
                            "is not in the URDF; the pair is skipped")
            continue
        disabled.append(DisabledCollision(str(a), str(b), d.get("reason", "User")))
    return Srdf(robot_name=root.get("name", ""), groups=groups, end_effectors=tuple(effs),
                states=tuple(states), disabled_collisions=tuple(disabled), source=source,
                warnings=tuple(warnings))


def starter_srdf(robot: Robot, groups: Mapping[str, Sequence[str]], tool_link: str) -> str:
    """A new SRDF for a model without one: the groups (``arm`` as a chain from the root
    to ``tool_link``, others as joint lists), an end effector ``gripper`` on
    ``tool_link`` when there is a ``gripper`` group, and a named state ``home`` of the
    arm (each joint at 0, or the bound of its range nearest 0). Disabled pairs are
    :func:`replace_disabled_collisions`' to add."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', f'<robot name="{robot.name}">']
    arm = list(groups.get("arm", robot.actuated_joints))
    lines.append(f'    <group name="arm">\n        <chain base_link="{robot.root}" '
                 f'tip_link="{tool_link}"/>\n    </group>')
    for name, joints in groups.items():
        if name in ("arm", "all"):
            continue
        body = "".join(f'\n        <joint name="{j}"/>' for j in joints)
        lines.append(f'    <group name="{name}">{body}\n    </group>')
    limits = robot.position_limits(tuple(arm))
    home = "".join(f'\n        <joint name="{j}" value="{float(min(max(0.0, lo), hi)):g}"/>'
                   for j, (lo, hi) in zip(arm, limits))
    lines.append(f'    <group_state name="home" group="arm">{home}\n    </group_state>')
    if "gripper" in groups:
        lines.append(f'    <end_effector name="gripper" parent_link="{tool_link}" '
                     'group="gripper" parent_group="arm"/>')
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


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
