"""Clients of the arduinobot service: the Python client and the `arduinobot` command.

- ``client``: the Python client; ``replies``, ``errors``, ``stream``, ``balance``: its parts.
- ``cloud_files``: .ply, .pcd, .xyz/.csv point clouds read into points to send.
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
