"""The allowed-collision matrix: link pairs the collision checker skips, and why.

It is read from the SRDF's ``<disable_collisions>`` (MoveIt's format); the pairs are
computed by :mod:`planner.acm_gen` (``arduinobot srdf``).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from description.srdf import DisabledCollision, Srdf


@dataclass(frozen=True)
class AllowedCollisionMatrix:
    """Unordered link (or link/obstacle) pairs allowed to touch, each with a reason."""

    entries: tuple[DisabledCollision, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "_pairs", {frozenset((e.link1, e.link2)): e.reason
                                            for e in self.entries})

    @classmethod
    def from_srdf(cls, srdf: Srdf | None) -> AllowedCollisionMatrix:
        return cls(tuple(srdf.disabled_collisions) if srdf is not None else ())

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
