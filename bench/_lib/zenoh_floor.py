"""The bare Zenoh get/reply floors ``./dev bench hop`` puts beside the service hop.

Three routes, each on loopback with a reply of the given bytes, a client-mode querier as
our client is, timed to its first reply (consolidation NONE, as a worker-answered query
would be read), after an optional idle gap before each get:

- ``bare``: the querier's peer answers itself (today's shape: the serving process holds
  the queryable);
- ``via_peer``: a queryable in another process, a client-mode session connected to the
  peer (issue 43's design: each worker connected to the serving process, which routes
  between its clients), the get sent with target ALL; the peer holds a complete
  queryable on the same key that answers nothing (as the supervisor would);
- ``direct``: as ``via_peer``, but the answering process is a peer listening on its own
  port and the querier a peer too (it meets the answerer by gossip and sends to it
  straight, no routing hop through the serving process).

The answering process is spawned (a fresh interpreter), never forked from this one: it
holds Zenoh sessions.
"""

from __future__ import annotations

import multiprocessing as mp
import statistics
import time
from typing import Literal

import numpy as np
import zenoh

from arduinobot.contract.zconfig import Mode, zenoh_config
from tests.helpers.serve import free_port

Route = Literal["bare", "via_peer", "direct"]
KEY = "hop/floor"


def stats(xs: list[float]) -> dict[str, float | None]:
    """Median and p95 of seconds, in ms."""
    if not xs:
        return {"median_ms": None, "p95_ms": None}
    return {"median_ms": round(1e3 * statistics.median(xs), 4),
            "p95_ms": round(1e3 * float(np.percentile(xs, 95)), 4)}


def _answer(connect: str, listen: str | None, reply: bytes, ready: object,
            stop: object) -> None:
    """The answering process (spawned): a queryable on KEY, not complete, replying
    ``reply`` to every query, until ``stop`` is set."""
    mode: Mode = "peer" if listen else "client"
    session = zenoh.open(zenoh_config(mode=mode, connect=[connect],
                                      listen=[listen] if listen else []))

    def on_query(q: zenoh.Query) -> None:
        q.reply(KEY, reply, encoding="application/json")
        q.drop()
    qbl = session.declare_queryable(KEY, on_query, complete=False)
    ready.set()  # type: ignore[attr-defined]
    stop.wait()  # type: ignore[attr-defined]
    qbl.undeclare()
    session.close()


def zenoh_floor(reply: bytes, repeats: int, *, gap: float = 0.0,
                route: Route = "bare") -> dict[str, float | None]:
    """A get/reply on loopback with ``reply`` as the answer by ``route`` (see the
    module); ``gap``: idle seconds before each get. The first 20 gets are not counted."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    srv = zenoh.open(zenoh_config(mode="peer", listen=[endpoint], connect=None))
    ctx = mp.get_context("spawn")
    ready, stop = ctx.Event(), ctx.Event()
    proc = None

    def on_query(q: zenoh.Query) -> None:
        if route == "bare":
            q.reply(KEY, reply, encoding="application/json")
        q.drop()
    qbl = srv.declare_queryable(KEY, on_query, complete=True)
    try:
        if route != "bare":
            listen = f"tcp/127.0.0.1:{free_port()}" if route == "direct" else None
            proc = ctx.Process(target=_answer, args=(endpoint, listen, reply, ready, stop),
                               daemon=True)
            proc.start()
            if not ready.wait(60):
                raise RuntimeError(f"the {route} answerer did not start")
        cli = zenoh.open(zenoh_config(mode="peer" if route == "direct" else "client",
                                      connect=[endpoint], listen=[]))
        target = zenoh.QueryTarget.BEST_MATCHING if route == "bare" else zenoh.QueryTarget.ALL
        try:
            times: list[float] = []
            i = 0
            while len(times) < repeats and i < repeats + 200:
                if gap:
                    time.sleep(gap)
                t = time.perf_counter()
                got = cli.get(KEY, payload=b'{"x":1}', target=target, timeout=5.0,
                              consolidation=zenoh.ConsolidationMode.NONE)
                first = None
                for r in got:  # the first reply; the rest (none) not waited for
                    first = r
                    break
                dt = time.perf_counter() - t
                del got
                # the answerer's route may take a moment to be declared: not counted
                if i >= 20 and first is not None and first.ok is not None:
                    times.append(dt)
                i += 1
            return stats(times)
        finally:
            cli.close()
    finally:
        qbl.undeclare()
        srv.close()
        stop.set()
        if proc is not None:
            proc.join(5)
            if proc.is_alive():
                proc.kill()
