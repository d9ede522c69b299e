"""Moving the service's robot: ``<prefix>/execute`` and its stream.

- ``execution``: the queryables (execute, cancel, robot_state) and the robot.
- ``run``: one execution's stream of events.
- ``io``: the execute request decoded, errors answered.
- ``twin_scene``: the world given to the MuJoCo twin.
"""
