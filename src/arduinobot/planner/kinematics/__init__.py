"""The robot's motion model.

- ``chain``: forward kinematics (a compiled chain of joint transforms).
- ``rotations``: rotations (Rodrigues, rpy, quaternions).
- ``dynamics``: the inverse-dynamics model (lumped links, payloads); ``rnea``: its
  compiled recursive Newton-Euler pass.
- ``ik``: position inverse kinematics (every branch); ``ik_numeric``: the numerical
  solver; ``ik_pose``: pose goals with free axes.
- ``limits``: the joint limits (URDF, joint_limits.yaml, derived).
- ``applied_limits``: the limits a plan was held to and where each came from (``info``,
  the plan summary, the viewer's plots).
"""
