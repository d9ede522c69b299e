"""Planning a motion: goals (goals), collision-free joint paths with OMPL (paths), the
request and result (motion), and the whole pipeline (pipeline, moving_start)."""
