"""A cylinder along z: ``radius`` and ``length`` [m]."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from arduinobot.scene.shapes.base import Shape, creation, fcl_module
from arduinobot.scene.shapes.checked import positive
from arduinobot.scene.shapes.registry import register

if TYPE_CHECKING:
    import fcl
    import trimesh

_CYLINDER_SECTIONS = 48
# sides of the prism that stands in for a cylinder's hull (circumscribed: it holds the
# cylinder, so its support is never short of the cylinder's)
_PRISM_SIDES = 24


@register
@dataclass(frozen=True)
class Cylinder(Shape):
    """A cylinder along its frame's z axis, centred on it; ``radius`` and ``length`` [m]."""

    radius: float
    length: float
    kind: ClassVar[str] = "cylinder"
    cli_form: ClassVar[str | None] = "r,l"

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        return positive(value, field)

    @classmethod
    def json_of_numbers(cls, values: Sequence[float]) -> dict[str, Any]:
        return {"radius": values[0], "length": values[1]}

    def grown(self, margin: float) -> Cylinder:
        return Cylinder.from_json({"radius": self.radius + margin,
                                   "length": self.length + 2 * margin}, where="shape")

    def contains(self, points: np.ndarray, padding: float = 0.0) -> np.ndarray:
        radial = points[:, 0] ** 2 + points[:, 1] ** 2 <= (self.radius + padding) ** 2
        return np.asarray(radial & (np.abs(points[:, 2]) <= self.length / 2 + padding))

    def triangles(self) -> trimesh.Trimesh:
        return creation().cylinder(radius=self.radius, height=self.length,
                                    sections=_CYLINDER_SECTIONS)

    def _unit_inertia(self) -> np.ndarray:
        r2, l2 = self.radius ** 2, self.length ** 2
        return np.diag([(3 * r2 + l2) / 12, (3 * r2 + l2) / 12, r2 / 2])

    def half_extents(self) -> np.ndarray:
        return np.array([self.radius, self.radius, self.length / 2])

    def reach(self) -> float:
        return math.hypot(float(self.radius), 0.5 * float(self.length))

    def hull_points(self) -> tuple[np.ndarray, float]:
        ang = 2 * np.pi * np.arange(_PRISM_SIDES) / _PRISM_SIDES
        r = self.radius / np.cos(np.pi / _PRISM_SIDES)
        ring = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
        return np.vstack([np.column_stack([ring, np.full(_PRISM_SIDES, z)])
                          for z in (-self.length / 2, self.length / 2)]), 0.0

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return fcl_module().Cylinder(self.radius, self.length)

    def mjcf(self) -> tuple[str, str]:
        return "cylinder", f"{float(self.radius)!r} {0.5 * float(self.length)!r}"
