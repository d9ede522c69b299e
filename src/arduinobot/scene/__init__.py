"""The scene: what is around the robot and what it carries.

One floor below the planner (it imports the contract and the description only).

- ``obstacles``: obstacles (box, sphere, cylinder, mesh) and attached objects.
- ``mesh_codec``: a mesh sent inline (STL/OBJ/PLY, base64) decoded and bounded.
- ``cloud``: a point cloud decoded and bounded, kept as occupied cells of a grid.
- ``cloud_filter``: the cells that are the robot's own or inside known objects, removed.
- ``cloud_spec``: a ``points`` object's fields checked (frame, pose, padding, camera).
- ``cloud_unknown``: a camera's frustum and its shadow, for ``unknown: "occupied"``.
"""
