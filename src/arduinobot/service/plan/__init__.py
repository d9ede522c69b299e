"""Answering plan, fk, ik and check in a worker.

- ``handlers``: one handler per key, a request's data to its reply.
- ``plan_io``: a plan request to a ``MotionRequest``, a result to its reply.
- ``requests``: the common request fields (obstacles, joints).
- ``bodies``: the collision bodies of a request's obstacles.
- ``recheck``: a running motion's rest certified against the kept scene now.
- ``task_recheck``: a running task's rest, each step's piece in that step's world.
"""
