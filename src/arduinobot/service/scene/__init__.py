"""The kept scene: one planning scene every plan and check uses, kept on disk and shared
by the instances.

The scene's model is :mod:`arduinobot.scene.state`'s (apply, attach and detach:
:mod:`arduinobot.scene.change`'s).

- ``apply``: ``<prefix>/scene/apply`` requests decoded, with the robot's state.
- ``carry``: the frames attach and detach need, asked of the worker pool.
- ``election``: the leader, among the live instances that answer.
- ``file``: the scene file.
- ``identity``: a scene's revision and digest (two scenes made apart told apart).
- ``members``: the instances sharing one scene.
- ``sync``: the leader and its followers.
- ``turns``: fair ``if_revision`` races (the loser goes next).
"""
