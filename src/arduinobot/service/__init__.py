"""The Zenoh service: ``arduinobot serve``, in wings.

- ``server``: the service itself: queryables under a prefix, a liveliness token, the pool.
- ``process/``: the worker pool and what a worker holds.
- ``plan/``: plan, fk, ik and check answered in a worker.
- ``scene/``: the kept scene, on disk and shared by the instances.
- ``execute/``: moving the service's robot, ``<prefix>/execute`` and its stream.
- ``task/``: ``<prefix>/task``, a pick and place planned as one request.
- ``local``: the request -> reply path in this process (``--local``).
- ``keyguard``: queryables that answer only a query naming their key exactly.
- ``messages``: what a job ends with, what the processes say to each other.
- ``router``: a plain Zenoh router (``python -m arduinobot.service.router``).
- ``hoptrace``: where a request's time goes (a debug probe, ``ARDUINOBOT_HOPTRACE``).
- ``security/``: the TLS configurations of the service, the router and a client (data).
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
