"""A box: ``size`` (x, y, z) [m]."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.shapes.base import Shape, box_unit_inertia, creation, fcl_module
from arduinobot.scene.shapes.checked import finite_vec
from arduinobot.scene.shapes.registry import register

if TYPE_CHECKING:
    import fcl
    import trimesh


@register
@dataclass(frozen=True)
class Box(Shape):
    """A box centred on its frame; ``size`` its edge lengths (x, y, z) [m]."""

    size: tuple[float, float, float]
    kind: ClassVar[str] = "box"
    cli_form: ClassVar[str | None] = "sx,sy,sz"
    has_surface: ClassVar[bool] = True

    @classmethod
    def _checked(cls, name: str, value: object, field: str) -> Any:
        if value is None:
            raise InvalidRequest("a box needs size (x, y, z) [m]", field=field)
        return finite_vec(value, 3, field, positive=True)

    @classmethod
    def json_of_numbers(cls, values: Sequence[float]) -> dict[str, Any]:
        return {"size": list(values)}

    def grown(self, margin: float) -> Box:
        return Box.from_json({"size": [x + 2 * margin for x in self.size]}, where="shape")

    def contains(self, points: np.ndarray, padding: float = 0.0) -> np.ndarray:
        half = np.asarray(self.size) / 2 + padding
        return np.asarray((np.abs(points) <= half).all(axis=1))

    def triangles(self) -> trimesh.Trimesh:
        return creation().box(extents=self.size)

    def _unit_inertia(self) -> np.ndarray:
        return box_unit_inertia(self.size)

    def half_extents(self) -> np.ndarray:
        return np.asarray(self.size, float) / 2

    def reach(self) -> float:
        return 0.5 * float(np.linalg.norm(self.size))

    def hull_points(self) -> tuple[np.ndarray, float]:
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        return corners * self.half_extents(), 0.0

    def collision_geometry(self) -> fcl.CollisionGeometry:
        return fcl_module().Box(*self.size)

    def surface(self) -> trimesh.Trimesh:
        return self.triangles()

    def mjcf(self) -> tuple[str, str]:
        return "box", " ".join(repr(float(v)) for v in self.half_extents())
