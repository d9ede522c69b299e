"""Plan with the Python client against a running `arduinobot serve`.

    ./dev arduinobot serve                      # one terminal: the service
    .venv/bin/python examples/01_plan.py        # another (or: 01_plan.py tcp/HOST:PORT)
"""

import json
import sys
import tempfile
from pathlib import Path

from arduinobot import PlannerClient
from arduinobot.client import errors
from arduinobot.client.replies import PlanReply

endpoint = sys.argv[1] if len(sys.argv) > 1 else "tcp/127.0.0.1:7447"

with PlannerClient(endpoint, timeout=30) as c:
    # a named state of the SRDF; the seed makes the planner's random choices repeatable
    res = c.plan(goal={"named": "reach_left"}, seed=1)
    print(f"reach_left: {res.duration:.3f} s, {len(res.times)} samples of {res.joint_names}")
    v = res.verification
    print(f"certified {v.certified}: at least {v.min_clearance * 1000:.1f} mm "
          f"between {v.closest_pair[0]} and {v.closest_pair[1]} over the whole motion")

    # a joint goal for the default group (arm: joint_1..joint_3), from that state
    start = dict(zip(res.joint_names, res.positions[-1]))
    back = c.plan(goal={"joints": {"joint_1": 0.5, "joint_2": 0.3, "joint_3": -0.4}},
                  start=start, profile="time_optimal", seed=1)
    print(f"then to the joint goal: {back.duration:.3f} s (time-optimal profile)")

    # what `arduinobot plan --json` writes reads back as the same reply
    saved = Path(tempfile.mkdtemp()) / "traj.json"
    saved.write_text(json.dumps(res.raw))
    again = PlanReply.parse(json.loads(saved.read_text()))
    print(f"saved and read back: {again.duration == res.duration}")

    # each error code is its own exception class, with the details the service sent
    try:
        c.plan(goal={"position": [0.0, 5.0, 0.0]})
    except errors.GoalOutOfReach as e:
        print(f"{e.code}: {e.message}")
