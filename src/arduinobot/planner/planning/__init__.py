"""Planning a motion: goals, collision-free joint paths with OMPL, and the strategies
behind one door (:class:`~.pipeline.MotionPlanner`).

- The request: ``motion`` (what a motion request asks and what a solved motion is),
  ``goals`` (the goal kinds), ``goal_states`` (goals resolved to joint states),
  ``tcp_goals`` (tcp positions and poses by inverse kinematics), ``reached`` (what a
  motion reached, against what its goal asked), ``resting`` (a carried object that
  starts on a support: lifted off by a line only).
- Strategies: ``context`` (what every strategy plans with), ``strategy`` (the
  interface), ``from_rest``, ``moving_start``, and ``pipeline`` (the one door over them).
- ``pathfinding/``: joint paths with OMPL (search, shortcuts, room, blended corners).
- ``lines/``: straight tool lines (Pilz's LIN): the strategy, the joint path, its timing.
"""
