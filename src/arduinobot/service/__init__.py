"""The planning service (``arduinobot serve``): Zenoh queryables over a worker pool.

- ``server``: the service (``PlannerService``, ``ServeOptions``): the plan keys, the
  pool, the kept scene, the extensions.
- ``queries``: the one queryable guard (exact keys, own threads, coded errors,
  INTERNAL for the rest) and the one error replier.
- ``extension``: what an extension is given (``Host``) and returns (``Running``).
- ``peers``: refusing to start beside a peer instance of the prefix with no router.
- ``keyguard``: whether a query names its key exactly (no wildcard).
- ``messages``: the jobs, outcomes and failures the pool passes.
- ``local``: the handlers in this process (``--local``), answering as the service.
- ``hoptrace``: per-request timestamps of each hop (``ARDUINOBOT_HOPTRACE``).
- ``router``: a Zenoh router for a cluster of instances.
- ``ros2_inputs``: ``serve --ros2``'s topics in: a PointCloud2 into the kept scene, a
  camera's latest image for perceive (the ``ros2`` extra, imported when they start).
- wings: ``process/`` (the pool, workers, zygote), ``plan/`` (plan, fk, ik, check
  bodies), ``scene/`` (the kept scene), ``execute/`` (moving the robot), ``task/``
  (``<prefix>/task``), ``perceive/`` (``<prefix>/perceive``: objects seen by a camera).
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
