"""Clients of the arduinobot service: the Python client and the `arduinobot` command."""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
