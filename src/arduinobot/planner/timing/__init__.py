"""From a path to a timed trajectory: blended curves (curve), jerk-limited and
time-optimal timing (ruckig_timing, toppra_timing), the sampled trajectory (trajectory),
its verification (verify) and braking along it (braking)."""
