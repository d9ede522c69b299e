"""The scene: what is around the robot and what it carries.

One floor below the planner (it imports the contract and the description only).

- ``obstacles``: obstacles (box, sphere, cylinder, mesh) and attached objects.
- ``mesh_codec``: a mesh sent inline (STL/OBJ/PLY, base64) decoded and bounded.
"""
