"""The Python client library of the arduinobot service (the command line is ``cli``, the
viewer ``viewer``).

- ``client``: :class:`~arduinobot.client.client.PlannerClient`, one session's queries.
- ``replies``: the service's replies as the client reads them (frozen dataclasses).
- ``errors``: the errors the client raises, one class per wire code.
- ``stream``: executing on the service's robot, its stream of events and cancel.
- ``balance``: which live instance a spreading client sends its next request to.
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
