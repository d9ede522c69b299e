"""A carried object's mass: what the dynamics of a robot that holds it must add."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Payload:
    """A rigid mass a link carries.

    Attributes:
        link: the link that holds it.
        mass: [kg], >= 0.
        com: its centre of mass in the link's frame [m], shape (3,).
        inertia: its inertia about its centre of mass in the link's axes [kg m^2],
            shape (3, 3).
    """

    link: str
    mass: float
    com: tuple[float, float, float]
    inertia: tuple[tuple[float, float, float], ...]
