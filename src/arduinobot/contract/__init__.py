"""The wire contract: what a client and the service agree on, and nothing else.

The ground floor: it imports only the standard library and small codecs (numpy, orjson,
jsonschema), never the planner, the service or a client.

- ``codes``: every error code (``Code``) and which keys answer which.
- ``errors``: the root error ``PlanningError`` and one class per code.
- ``ranges``: the numeric ranges of request fields.
- ``caps``: the size caps of a request and the cheap structural check.
- ``wire``: strict JSON in and out, the schemas' validators.
- ``outcomes``: how an execution ended (``completed``, ``written``, ``cancelled``,
  ``stopped``) and what it does when the world changes (``on_change``).
- ``packed``: a trajectory's samples packed (base64 of float64 arrays).
- ``inline``: bytes sent inline in a JSON field (base64), decoded within a size cap.
- ``samples``: a trajectory's samples as CSV (``samples_csv``).
- ``zconfig``: the Zenoh configuration of the service and its clients.
- ``schema/``: the JSON Schemas, as published on ``<prefix>/schema``.
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
