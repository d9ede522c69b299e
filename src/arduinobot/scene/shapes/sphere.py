"""A ball: ``radius`` [m]."""

from __future__ import annotations

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

_SPHERE_SUBDIVISIONS = 3  # the icosphere drawn for a sphere


@register
@dataclass(frozen=True)
class Sphere(Shape):
    """A ball centred on its frame; ``radius`` [m]."""

    radius: float
    kind: ClassVar[str] = "sphere"
    cli_form: ClassVar[str | None] = "r"

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        return positive(value, field)

    @classmethod
    def json_of_numbers(cls, values: Sequence[float]) -> dict[str, Any]:
        return {"radius": values[0]}

    def grown(self, margin: float) -> Sphere:
        return Sphere.from_json({"radius": self.radius + margin}, where="shape")

    def contains(self, points: np.ndarray, padding: float = 0.0) -> np.ndarray:
        return np.asarray(np.einsum("ij,ij->i", points, points)
                          <= (self.radius + padding) ** 2)

    def triangles(self) -> trimesh.Trimesh:
        return creation().icosphere(subdivisions=_SPHERE_SUBDIVISIONS, radius=self.radius)

    def _unit_inertia(self) -> np.ndarray:
        return np.eye(3) * 0.4 * self.radius ** 2

    def half_extents(self) -> np.ndarray:
        return np.full(3, self.radius)

    def reach(self) -> float:
        return float(self.radius)

    def hull_points(self) -> tuple[np.ndarray, float]:
        return np.zeros((1, 3)), float(self.radius)

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return fcl_module().Sphere(self.radius)

    def mjcf(self) -> tuple[str, str]:
        return "sphere", repr(float(self.radius))
