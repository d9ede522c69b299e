"""Collision-free joint paths with OMPL.

- ``paths``: joint-space path planning (search, simplify, prove).
- ``search``: one OMPL search and OMPL's process-wide settings.
- ``shortcut``: simplifying a found path, judged by the caller's edge check.
- ``room``: the room kept per pair, the worlds detours are searched in.
- ``blended``: a found path and its blended corners proven in one walk.
"""
