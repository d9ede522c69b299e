"""The robot's motion model.

- ``chain``: forward kinematics of every link, one joint vector or a batch.
- ``dynamics``: inverse dynamics (recursive Newton-Euler) from the URDF's inertials;
  ``rnea``: its compiled pass over a batch of states.
- ``ik``: position IK of the tool centre point (every solution, or why none);
  ``ik_numeric``: its generic numeric part; ``ik_pose``: the tool's pose, Jacobian, pose
  IK and following a target.
- ``limits``: every joint limit the planner and the timing use, with its source.
- ``rotations``: quaternions (x, y, z, w), roll-pitch-yaw, rotation vectors.
"""
