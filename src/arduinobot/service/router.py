"""A plain Zenoh router for arduinobot services and clients: ``python -m arduinobot.service.router``.

The pip package ``eclipse-zenoh`` has no ``zenohd``; this is the same router, as a
session in router mode, so a deployment (and the tests) can run one without the service
in it. It takes the same JSON5 config as ``arduinobot serve --config`` (TLS,
user/password, access control: see ``src/arduinobot/service/security/router.json5``), with multicast
scouting off unless asked. It prints nothing but its log; SIGINT or SIGTERM stop it.

    python -m arduinobot.service.router --config src/arduinobot/service/security/router.json5
    python -m arduinobot.service.router --listen tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading

import zenoh

from arduinobot.contract.zconfig import DEFAULT_ENDPOINT, zenoh_config, zenoh_message

_log = logging.getLogger(__name__)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m arduinobot.service.router",
        description="Run a Zenoh router (what zenohd does) for arduinobot services and "
        "clients. Default: tcp/127.0.0.1:7447, multicast scouting off.")
    p.add_argument("--listen", action="append", metavar="ENDPOINT",
                   help="an endpoint to listen on, repeatable (default tcp/127.0.0.1:7447; "
                   "with --config, the file's)")
    p.add_argument("--connect", action="append", metavar="ENDPOINT",
                   help="another router to connect to, repeatable")
    p.add_argument("--config", metavar="FILE", help="a zenoh JSON5 config (TLS, "
                   "user/password, access control); options given here override it")
    p.add_argument("--multicast-scouting", action="store_true",
                   help="announce the router on the LAN (off by default, even with --config)")
    ns = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    listen = ns.listen if ns.listen or ns.config else [DEFAULT_ENDPOINT]
    cfg = zenoh_config(mode="router", listen=listen, connect=ns.connect,
                       config_file=ns.config, multicast_scouting=ns.multicast_scouting)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        session = zenoh.open(cfg)
    except zenoh.ZError as e:
        print(f"arduinobot.service.router: cannot start: {zenoh_message(e)}", file=sys.stderr)
        return 1
    _log.info("router %s ready, listening on %s", session.zid(),
              ", ".join(listen or ["(the config's endpoints)"]))
    try:
        while not stop.wait(0.5):  # short waits keep the signal handler responsive
            pass
    finally:
        session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
