"""Straight lines of the tool (Pilz's LIN).

- ``straight_line``: the LIN strategy.
- ``line_path``: a straight tcp line followed by the joints.
- ``line_timing``: its timing within the Cartesian limits.
"""
