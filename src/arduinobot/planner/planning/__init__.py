"""Planning a motion: goals, collision-free joint paths with OMPL, and the strategies
behind one door (:class:`~.pipeline.MotionPlanner`).

- The request: ``motion`` (what a motion request asks and what a solved motion is),
  ``goals`` (the goal kinds), ``goal_states`` (goals resolved to joint states),
  ``tcp_goals`` (tcp positions and poses by inverse kinematics), ``reached`` (what a
  motion reached, against what its goal asked).
- Paths: ``paths`` (joint-space path planning with OMPL), ``search`` (one OMPL search and
  OMPL's process-wide settings), ``shortcut`` (simplifying a found path), ``room`` (the
  room kept per pair: the worlds detours are searched in), ``blended`` (a found path and
  its blended corners proven in one walk).
- Straight lines: ``straight_line`` (Pilz's LIN), ``line_path`` (following a tcp line with
  the joints), ``line_timing`` (timing it within the Cartesian limits).
- Strategies: ``context`` (what every strategy plans with), ``strategy`` (the
  interface), ``from_rest``, ``moving_start``, and ``pipeline`` (the one door over them).
"""
