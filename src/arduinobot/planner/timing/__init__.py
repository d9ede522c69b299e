"""From a path to a timed trajectory.

- ``curve``: the blended curve both timings follow; ``curve_eval``: its states under
  polynomial profiles, compiled.
- ``profiles``: the registry of timing profiles; ``ruckig_timing``: jerk-limited (the
  default); ``toppra_timing``: time-optimal.
- ``trajectory``: the timed trajectory, sampled for motors.
- ``verify``: every limit between samples, and collisions, before a trajectory is returned.
- ``braking``: a moving arm braked to rest within the effort limits.
"""
