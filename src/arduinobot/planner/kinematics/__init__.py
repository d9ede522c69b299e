"""The robot's motion model: forward kinematics (chain), inverse dynamics (dynamics),
inverse kinematics (ik, ik_numeric) and the joint limits (limits)."""
