"""Obstacles in a plan request: the plan goes around them, or says why it cannot.

Each request carries its own obstacles (boxes, spheres and cylinders placed in the
robot's base frame, in metres), checked with the service's kept scene (empty unless
``arduinobot scene`` put objects in it, docs/service.md); a request's obstacles are not
kept after it.

    .venv/bin/python examples/03_scene.py [ENDPOINT]   # with `arduinobot serve` running
"""

import sys

from arduinobot import PlannerClient
from arduinobot.client import errors

endpoint = sys.argv[1] if len(sys.argv) > 1 else "tcp/127.0.0.1:7447"

# halfway along the tool's way from the start (all joints 0) to reach_left
ball = {"id": "ball", "shape": "sphere", "radius": 0.2, "xyz": [-0.67, 0.69, 2.24]}
table = {"id": "table", "shape": "box", "size": [1.0, 1.0, 0.1], "xyz": [0.0, 1.0, 0.5]}


def show(what: str, res) -> None:
    v = res.verification
    print(f"{what}: {res.duration:.3f} s through {len(res.path)} waypoints ({res.planner}), "
          f"min clearance {v.min_clearance * 1000:.1f} mm, {v.closest_pair[0]} to "
          f"{v.closest_pair[1]}")


with PlannerClient(endpoint, timeout=30) as c:
    show("reach_left, nothing in the way", c.plan(goal={"named": "reach_left"}, seed=1))
    # the straight line would cross the ball: the planner finds a way around it, and the
    # whole motion is proven to keep clear, not just its samples
    show("reach_left around a ball", c.plan(goal={"named": "reach_left"}, obstacles=[ball],
                                            seed=1))
    show("a position above a table", c.plan(goal={"position": [0.0, 1.0, 1.2]},
                                            obstacles=[table], seed=1))

    # a state can be checked on its own, among the same obstacles
    state = c.check_state({"joint_2": 0.5}, obstacles=[ball, table])
    print(f"joint_2 = 0.5 among them: valid {state.valid}")

    # a goal inside an obstacle is refused, naming the pairs that touch
    try:
        c.plan(goal={"named": "reach_left"}, seed=1,
               obstacles=[{**ball, "radius": 0.1, "xyz": [-0.06, -0.14, 2.71]}])
    except errors.GoalInCollision as e:
        print(f"{e.code}: {e.message}")
