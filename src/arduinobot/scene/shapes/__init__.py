"""The shapes of the scene: one frozen class per kind, each the only place that knows its
dimensions.

A shape validates itself (errors name ``<where>.<field>``), reads and writes its JSON
dimension fields (the ``shape`` name and the pose belong to the obstacle), gives its key
(what it is as written) and content key (what its geometry depends on), its triangles,
its unit inertia, its collision geometry, its MuJoCo geom and its command-line form.
Consumers ask the shape; none switches on its kind.

A new kind (a point cloud) is one new module here, its class under :func:`register`,
and its import below (the import order is the registry's).

- ``base``: :class:`Shape`, what every kind answers, and the geometry helpers they share.
- ``registry``: the kinds by their JSON ``shape`` name (:func:`register`,
  :func:`shape_class`, :func:`kinds`, :func:`dimension_fields`, :func:`check_inline`).
- ``checked``: dimension values checked (:func:`finite_vec`, :func:`positive`).
- ``box``, ``sphere``, ``cylinder``, ``mesh``: the kinds, one module each.
"""

from arduinobot.scene.shapes.base import Shape, box_unit_inertia
from arduinobot.scene.shapes.checked import finite_vec, positive
from arduinobot.scene.shapes.registry import (
    check_inline,
    dimension_fields,
    kinds,
    register,
    shape_class,
)

# the kinds, in the registry's order (error messages and the command line list them so)
# isort: off
from arduinobot.scene.shapes.box import Box
from arduinobot.scene.shapes.sphere import Sphere
from arduinobot.scene.shapes.cylinder import Cylinder
from arduinobot.scene.shapes.mesh import Mesh
# isort: on

__all__ = [
    "Box", "Cylinder", "Mesh", "Shape", "Sphere", "box_unit_inertia", "check_inline",
    "dimension_fields", "finite_vec", "kinds", "positive", "register",
    "shape_class",
]
