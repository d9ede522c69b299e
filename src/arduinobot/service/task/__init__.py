"""Tasks: ``<prefix>/task``, a pick and place planned as one request.

- ``task_service``: the queryable, the worker's job and the named tasks.
"""
