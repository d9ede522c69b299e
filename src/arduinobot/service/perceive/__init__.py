"""Perceive: ``<prefix>/perceive``, objects seen through markers in a camera image, and
put into the kept scene on request (issue 41).

- ``perceive_service``: the queryable: decodes the request, runs
  :mod:`arduinobot.perception` (OpenCV: the ``see`` extra, imported on the first request)
  and applies what it saw through ``<prefix>/scene/apply``.
"""
