"""Planning a motion: from a request to a verified trajectory.

- ``pipeline``: the one door, :class:`~arduinobot.planner.planning.pipeline.MotionPlanner`.
- ``motion``: the request and the result; ``reached``: what a motion reached.
- ``context``: what every strategy plans with, built once per robot; ``strategy``: the
  interface of a strategy; ``from_rest``, ``moving_start``, ``straight_line``: the
  strategies.
- ``goals``: the goal kinds; ``goal_states``: goals resolved to joint states;
  ``tcp_goals``: tcp positions and poses resolved by IK.
- ``paths``: joint-space paths with OMPL; ``search``: one OMPL search and OMPL's
  settings; ``shortcut``: path simplification; ``room``: the worlds detours are
  searched in; ``blended``: a path and its blended corners proven in one walk.
- ``line_path``: a straight tcp line followed by the joints; ``line_timing``: its timing.
"""
