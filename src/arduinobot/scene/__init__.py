"""The scene: what is around the robot and what it carries.

On the contract, below the description: a link's geometry is a scene shape
(:mod:`arduinobot.description.geometry`), so the robot and what is around it share one
shape model; the scene knows the robot only through the frames protocol.

- ``shapes/``: one frozen class per shape (box, sphere, cylinder, mesh), a registry by
  the JSON ``shape`` name; a new kind is one module there.
- ``obstacles``: obstacles (a shape placed in the world) and attached objects.
- ``ground``: the plane the base stands on, an obstacle by default.
- ``frames``: attach and detach, once, for the kept scene and tasks, behind a small
  frames protocol (link poses, contacts), with the one contact rule.
- ``state``: the kept scene's model: its state at a revision, what a plan takes of it.
- ``builder``: a wire object made an object of the kept scene (meshes stored).
- ``change``: how an apply changes the kept scene (all or nothing), and restore.
- ``pose``: URDF roll-pitch-yaw and rotation matrices, both ways (objects and links).
- ``payload``: a carried object's mass, centre of mass and inertia on its link.
- ``mesh_codec``: a mesh sent inline (STL/OBJ/PLY, base64) decoded and bounded.
- ``cloud``: a point cloud decoded and bounded, kept as occupied cells of a grid.
- ``cloud_filter``: the cells that are the robot's own or inside known objects, removed.
- ``cloud_spec``: a ``points`` object's fields checked (frame, pose, padding, camera).
- ``cloud_unknown``: a camera's frustum and its shadow, for ``unknown: "occupied"``.
"""
