"""Zenoh session configuration shared by the service, the client and the tests.

Importing this module does not import zenoh (only :func:`zenoh_config` does), so the
command line's ``--local`` path can read the defaults without it."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from arduinobot.contract.errors import InvalidRequest

if TYPE_CHECKING:
    import zenoh

Mode = Literal["peer", "client", "router"]

#: Where ``arduinobot serve`` listens and the client connects by default.
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
DEFAULT_PREFIX = "arduinobot"
#: What no chunk of a prefix may hold: Zenoh's wildcards (``*``, ``**``, ``$*``) and the
#: characters it reserves (``#``, ``?``), whitespace.
_NOT_LITERAL = frozenset("*$#? \t\r\n")


#: where Zenoh's Rust build says an error came from (`` at /root/.cargo/git/checkouts/
#: zenoh-.../orchestrator.rs:447.``): nothing a user can act on
_RUST_SOURCE = re.compile(r"\s+at\s+\S+\.rs:\d+(?::\d+)?\.?")
#: a config error's wrapping (``Json5Err(Message { msg: "...", location: ... })``)
_JSON5_WRAP = re.compile(r'Json5Err\(Message \{ msg: "(.*?)", location: .*\}\)')


def zenoh_message(error: BaseException) -> str:
    """What Zenoh says went wrong, without the Rust source paths of its build and the
    wrapping of its config parser: the text a user reads."""
    text = _RUST_SOURCE.sub("", str(error))
    return _JSON5_WRAP.sub(lambda m: m.group(1), text).strip()


def check_prefix(prefix: str) -> str:
    """``prefix`` if it is a literal key expression (chunks of ordinary characters
    between single ``/``), else InvalidRequest naming ``prefix``: a wildcard prefix
    (``*``) would make a service answer every other prefix's keys."""
    chunks = prefix.split("/") if isinstance(prefix, str) else [""]
    bad = sorted({c for c in prefix if c in _NOT_LITERAL}) if isinstance(prefix, str) else []
    if bad or any(not c for c in chunks):
        raise InvalidRequest(
            f"{prefix!r} must be literal chunks joined by single '/' (no "
            + (", ".join(repr(c) for c in bad) if bad else "empty chunk") + ")",
            field="prefix")
    return prefix


def zenoh_config(*, mode: Mode | None = None, listen: Sequence[str] | None = None,
                 connect: Sequence[str] | None = None, config_file: str | Path | None = None,
                 multicast_scouting: bool = False, shared_memory: bool = False
                 ) -> zenoh.Config:
    """A session config: ``config_file`` (zenoh JSON5: TLS, user/password, access
    control, ...) if given, then each explicit option on top of it.

    Multicast scouting is set off unless ``multicast_scouting``: a service does not
    announce itself on the LAN unless asked, even when a config file leaves it at
    zenoh's default (on).

    Zenoh's shared-memory transport is set off unless ``shared_memory``: with it (zenoh
    1.10's default) every peer on the host that sends a message over 3 KB makes a 16 MiB
    pool that this process maps and keeps mapped after the peer has gone, so a
    long-running service or router grows 16 MiB per client ever connected (measured by
    bench/soak.py); over loopback TCP our messages (at most 256 KiB) lose nothing.
    """
    import zenoh

    cfg = zenoh.Config.from_file(str(config_file)) if config_file else zenoh.Config()
    if mode is not None:
        cfg.insert_json5("mode", json.dumps(mode))
    if listen is not None:
        cfg.insert_json5("listen/endpoints", json.dumps(list(listen)))
    if connect is not None:
        cfg.insert_json5("connect/endpoints", json.dumps(list(connect)))
    cfg.insert_json5("scouting/multicast/enabled", json.dumps(bool(multicast_scouting)))
    cfg.insert_json5("transport/shared_memory/enabled", json.dumps(bool(shared_memory)))
    return cfg
