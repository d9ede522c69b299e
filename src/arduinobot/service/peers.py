"""Two instances of one prefix as Zenoh peers, with no router between them, both answer
every query on a shared key: a plan runs twice, a scene apply is applied twice (the
client hears "duplicate id" for a change that was made), one execute moves both robots.
Behind a router each query reaches one of them. So an instance that finds another live
instance of its prefix while it reaches no router refuses to start, saying why and what
to do instead (:func:`refuse_peer_instances`).
"""

from __future__ import annotations

import logging

import zenoh

_log = logging.getLogger(__name__)

#: [s] how long the start waits for the other instances' liveliness tokens
ASK_WAIT = 3.0


class PeerInstances(RuntimeError):
    """Another instance of this prefix is reachable as a peer and no router is."""

    def __init__(self, message: str, *, prefix: str, instances: tuple[str, ...]) -> None:
        super().__init__(message)
        self.prefix = prefix
        self.instances = instances


def refuse_peer_instances(session: zenoh.Session, prefix: str, *,
                          wait: float = ASK_WAIT) -> None:
    """Return if ``session`` reaches a router or no other instance of ``prefix`` lives.

    Raises:
        PeerInstances: naming the other instances and the ways out.
    """
    info = session.info
    if list(info.routers_zid()) or not list(info.peers_zid()):
        return  # behind a router (one reply per query), or alone
    others = tuple(sorted(str(r.ok.key_expr).rsplit("/", 1)[-1]
                          for r in session.liveliness().get(f"{prefix}/alive/*", timeout=wait)
                          if r.ok is not None))
    if others:
        raise PeerInstances(
            f"another arduinobot instance of prefix '{prefix}' is reachable as a Zenoh peer "
            f"({', '.join(others)}) with no router between: every query on {prefix}/* "
            "would reach both (a plan twice, a scene change applied twice, one execute "
            "moving both robots). Put a router between the instances (`python -m "
            "arduinobot.service.router --listen tcp/0.0.0.0:7447`, then `serve --mode "
            "client --connect` to it), or give this one its own --prefix",
            prefix=prefix, instances=others)
    _log.debug("peers reached, no other instance of %s", prefix)
