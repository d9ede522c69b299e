"""Tasks: ``<prefix>/task``, a pick and place planned as one request.

- ``task_service``: the queryable, the worker's job and the named tasks (the client
  that runs a named task is ``arduinobot.client.named_task``).
- ``pieces``: the joined motion cut into its steps' worlds, for re-checking it running.
"""
