"""The scene: what is around the robot and what it carries.

One floor below the planner (it imports the contract and the description only).

- ``shapes``: one frozen class per shape (box, sphere, cylinder, mesh), a registry by
  the JSON ``shape`` name; a new kind is one class here.
- ``obstacles``: obstacles (a shape placed in the world) and attached objects.
- ``ground``: the plane the base stands on, an obstacle by default.
- ``frames``: attach and detach, once, for the kept scene and tasks, behind a small
  frames protocol (link poses, contacts), with the one contact rule.
- ``state``: the kept scene's model: its state at a revision, apply, restore.
- ``payload``: a carried object's mass, centre of mass and inertia on its link.
- ``mesh_codec``: a mesh sent inline (STL/OBJ/PLY, base64) decoded and bounded.
- ``cloud``: a point cloud decoded and bounded, kept as occupied cells of a grid.
- ``cloud_filter``: the cells that are the robot's own or inside known objects, removed.
- ``cloud_spec``: a ``points`` object's fields checked (frame, pose, padding, camera).
- ``cloud_unknown``: a camera's frustum and its shadow, for ``unknown: "occupied"``.
"""
