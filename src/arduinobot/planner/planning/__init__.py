"""Planning a motion: goals (goals), collision-free joint paths with OMPL (paths), the
request and result (motion), what every strategy plans with (context), the strategies
(strategy: the interface; from_rest, moving_start) and the one door over them
(pipeline.MotionPlanner)."""
