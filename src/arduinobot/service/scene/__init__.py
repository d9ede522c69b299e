"""The kept scene: one planning scene every plan and check uses, kept on disk and shared
by the instances.

- ``store``: the scene's state, snapshots and revisions, on disk.
- ``apply``: ``<prefix>/scene/apply`` requests decoded and applied.
- ``carry``: attach and detach (objects carried by a link).
- ``file``: the scene file.
- ``members``: the instances sharing one scene.
- ``sync``: the leader and its followers.
"""
