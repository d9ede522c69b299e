"""Execute on the MuJoCo twin: plan through the service, then play the trajectory on a
physics model of the arm (meshes, inertias, servos capped at the motors' effort) and
read what happened, as `arduinobot execute traj.json --sim` does.

Needs the twin's extra (`pip install -e '.[sim]'`). The first run on a
model decomposes its meshes for MuJoCo (V-HACD: tens of seconds); the user's artifact
cache (the one `serve` and `execute --sim` use) keeps them for the next.

    .venv/bin/python examples/04_execute_twin.py [ENDPOINT]   # with `arduinobot serve` running
"""

import sys

from arduinobot import PlannerClient
from arduinobot.description import load_description
from arduinobot.execution.executor import ExecuteOptions, Executor, plan_start
from arduinobot.execution.robots.sim_arduinobot import SimArduinobot
from arduinobot.execution.segments import SampledTrajectory
from arduinobot.service.process.disk_cache import DiskCache

endpoint = sys.argv[1] if len(sys.argv) > 1 else "tcp/127.0.0.1:7447"
desc = load_description()  # the shipped arduinobot: the model `serve` runs by default

with SimArduinobot(desc, cache=DiskCache()) as twin, PlannerClient(endpoint, timeout=30) as c:
    # plan from where the twin is: execution refuses a trajectory that starts elsewhere
    res = c.plan(goal={"named": "reach_left"}, start=plan_start(twin, desc), seed=1)
    traj = SampledTrajectory.of(res)  # the reply's samples, parsed once

    # realtime=False: simulated time runs as fast as it computes (the real arm is paced)
    ex = Executor.for_description(twin, desc, options=ExecuteOptions(realtime=False))
    report = ex.execute(ex.check_start(traj))

    print(f"{report.outcome}: {report.duration:.3f} s, {report.ticks} ticks at 100 Hz")
    print("peaks against the limits: "
          + ", ".join(f"{k} {v:.0%}" for k, v in report.peak_ratio.items()))
    print("tracking error per joint: "
          + ", ".join(f"{n} {e * 1000:.2f} mrad"
                      for n, e in zip(report.joint_names, report.max_tracking_error)))
    stats = twin.stats()
    print("servo peak force / effort limit: "
          + ", ".join(f"{p:.1f}/{lim:.0f}" for p, lim in zip(stats.peak_force, stats.effort))
          + f"; contacts: {list(stats.contacts) or 'none'}")
