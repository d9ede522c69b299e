"""The Python client library of the arduinobot service; it imports only the contract
(and zenoh, numpy, orjson, jsonschema-rs), never the planner, the service or the CLI.

- ``client``: :class:`PlannerClient` (plan, fk, ik, check, execute, task, scene, apply,
  update, perceive).
- ``codec``: a request's payload and a reply's JSON (``encode_body``, ``decode_reply``).
- ``replies``: the frozen reply dataclasses, each checked against its schema.
- ``errors``: one class per wire code under ``ServiceError``.
- ``stream``: the one follower of an execute or task stream (with cancel).
- ``named_task``: a named task run for a progress-only caller (the ROS 2 task server).
- ``balance``: the load balancer of ``spread=True``.
- ``cloud_files``: .ply, .pcd, .xyz/.csv point clouds read into points to send.
- ``scene_update``: a read-modify-write of the kept scene that takes turns when racing.
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
