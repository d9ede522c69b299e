"""The allowed-collision matrix: link pairs the collision checker skips, and why.

Links joined by a joint are always allowed (they touch by construction), and so are
links held rigidly together by fixed joints (a camera bolted to the base): whatever the
SRDF says, and with no SRDF at all. The SRDF's ``<disable_collisions>`` (MoveIt's
format) add to that; :mod:`arduinobot.planner.collision.acm_gen` computes them (``arduinobot srdf``) and
:mod:`arduinobot.planner.collision.acm_proof` proves pairs that can never touch.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from arduinobot.description import Description
from arduinobot.description.model import Robot
from arduinobot.description.srdf import DisabledCollision, Srdf


def adjacent_pairs(robot: Robot, bodies: Iterable[str]) -> set[frozenset[str]]:
    """Pairs of ``bodies`` (links with collision geometry) joined by a joint, walking up
    through links without geometry as MoveIt does, plus every pair of a rigid cluster
    (links joined by chains of fixed joints, which can never move apart)."""
    bodies = set(bodies)
    out: set[frozenset[str]] = set()
    parent = robot.parent_joint
    for link in bodies:
        cur = link
        while cur in parent:
            up = parent[cur].parent
            if up in bodies:
                out.add(frozenset((link, up)))
                break
            cur = up
    cluster: dict[str, str] = {}
    for j in robot.topological_joints:
        cluster.setdefault(j.parent, j.parent)
        cluster[j.child] = cluster[j.parent] if j.type == "fixed" else j.child
    members: dict[str, list[str]] = {}
    for link in sorted(bodies):
        members.setdefault(cluster.get(link, link), []).append(link)
    for group in members.values():
        out.update(frozenset((a, b)) for i, a in enumerate(group) for b in group[i + 1:])
    return out


@dataclass(frozen=True)
class AllowedCollisionMatrix:
    """Unordered link (or link/obstacle) pairs allowed to touch, each with a reason."""

    entries: tuple[DisabledCollision, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "_pairs", {frozenset((e.link1, e.link2)): e.reason
                                            for e in self.entries})

    @classmethod
    def from_srdf(cls, srdf: Srdf | None) -> AllowedCollisionMatrix:
        """The SRDF's disabled pairs, except ``Never-sampled`` ones: recorded for MoveIt,
        but a sample that missed a contact is no proof, so they stay checked here."""
        if srdf is None:
            return cls()
        return cls(tuple(d for d in srdf.disabled_collisions if d.reason != "Never-sampled"))

    @classmethod
    def for_description(cls, description: Description) -> AllowedCollisionMatrix:
        """Joint-connected and rigidly attached links, then the SRDF's pairs."""
        robot = description.robot
        bodies = [n for n, link in robot.links.items() if link.collisions]
        adjacent = sorted((min(p), max(p)) for p in adjacent_pairs(robot, bodies))
        return cls.from_pairs(adjacent, reason="Adjacent").with_entries(
            cls.from_srdf(description.srdf).entries)

    def with_entries(self, entries: Iterable[DisabledCollision]) -> AllowedCollisionMatrix:
        """A copy that also allows ``entries`` (pairs already allowed keep their reason)."""
        return AllowedCollisionMatrix(self.entries + tuple(
            e for e in entries if not self.allowed(e.link1, e.link2)))

    @classmethod
    def from_pairs(cls, pairs: Iterable[tuple[str, str]], *,
                   reason: str = "User") -> AllowedCollisionMatrix:
        return cls(tuple(DisabledCollision(a, b, reason) for a, b in pairs))

    def allowed(self, a: str, b: str) -> bool:
        """True if the pair ``a``/``b`` is not checked."""
        return frozenset((a, b)) in self._pairs  # type: ignore[attr-defined]

    def reason(self, a: str, b: str) -> str | None:
        """Why the pair is allowed, or None if it is checked."""
        return self._pairs.get(frozenset((a, b)))  # type: ignore[attr-defined]

    def with_pairs(self, pairs: Iterable[tuple[str, str]], *,
                   reason: str = "User") -> AllowedCollisionMatrix:
        """A copy that also allows ``pairs``."""
        return AllowedCollisionMatrix(self.entries + tuple(
            DisabledCollision(a, b, reason) for a, b in pairs if not self.allowed(a, b)))

    def __iter__(self) -> Iterator[DisabledCollision]:
        return iter(self.entries)

    def __len__(self) -> int:
        return len(self.entries)
