"""Moving the service's robot: ``<prefix>/execute`` and its stream.

- ``execution``: the queryables (execute, cancel, robot_state) and the robot.
- ``run``: one execution's stream of events.
- ``io``: the execute request decoded, the errors it answers as themselves.
- ``twin_scene``: the world given to the MuJoCo twin.
- ``react``: every scene change re-checks a moving arm's rest; stop, replan or go on.
- ``task_react``: a running task's rest cut by its steps, each checked in its own world.
- ``task_replan``: a stopped task's remaining steps planned again from where it stopped.
"""
