"""The one guard of the service's queryables and its one error replier.

Every queryable of every wing (the plan keys, the kept scene, execute, task) is declared
through :func:`guarded`: a work key answers only a query naming it exactly
(:mod:`arduinobot.service.keyguard`), a handler that waits (for the pool, a robot, a whole
execution) runs on its own thread rather than Zenoh's (shared by every queryable), a
coded error answers as itself and anything else is logged and answered ``INTERNAL``: a
querier always hears why, and a bug never takes the service down.
"""

from __future__ import annotations

import logging
import threading
import traceback
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any, Protocol

import zenoh

from arduinobot.contract import wire
from arduinobot.contract.codes import Code
from arduinobot.contract.errors import PlanningError
from arduinobot.service.keyguard import addressed_exactly
from arduinobot.service.messages import Failure

_log = logging.getLogger(__name__)


class Coded(Protocol):
    """An error with a wire code: a :class:`PlanningError`, a robot's ``RobotError``."""

    code: str
    message: str
    details: Mapping[str, Any]


def _coded(e: BaseException) -> tuple[str, str, Mapping[str, Any]]:
    """A coded error's code, message and details (:class:`Coded`)."""
    c: Coded = e  # type: ignore[assignment]  # each coded class has the three
    return str(c.code), c.message, c.details


def reply_error(query: zenoh.Query, code: str, message: str,
                details: Mapping[str, Any] | None = None) -> None:
    """Answer ``query`` with the error reply ``{"error": {code, message, details}}``."""
    query.reply_err(wire.encode(wire.error_json(code, message, details)),
                    encoding=wire.JSON)


def reply_failure(query: zenoh.Query, failure: Failure) -> None:
    """Answer ``query`` with a job's coded ``failure``."""
    reply_error(query, failure.code, failure.message, failure.details)


@contextmanager
def answering(query: zenoh.Query, where: str, *, internal: str | None = None,
              coded: tuple[type[Exception], ...] = (PlanningError,),
              log_refusals: bool = False) -> Iterator[None]:
    """A ``coded`` error in the block answers ``query`` as itself (logged as a warning
    with ``log_refusals``); any other is logged and answered INTERNAL with the message
    ``internal`` (None: the exception's own text)."""
    try:
        yield
    except coded as e:
        # read, not bound to a name: a name holding the exception would hold its
        # traceback, this frame and the query with it, and the querier's get would not
        # end until the collector ran
        c = _coded(e)
        if log_refusals:  # a refused motion is news to whoever watches the log
            _log.warning("%s: refused %s: %s", where, c[0], c[1])
        reply_error(query, *c)
    except Exception as e:  # noqa: BLE001 -- logged; the querier gets INTERNAL
        # the traceback as text: a log record holding it (a handler that keeps records)
        # would hold the query too, and the querier's get would not end
        _log.error("%s: unexpected failure\n%s", where, traceback.format_exc().rstrip())
        if internal is not None:
            reply_error(query, Code.INTERNAL, internal)
        else:
            reply_error(query, Code.INTERNAL, f"{type(e).__name__}: {e}",
                        {"exception": type(e).__name__})


def guarded(key: str, handler: Callable[[zenoh.Query], None], *, exact: bool,
            threaded: bool = False, internal: str = "unexpected failure in the service",
            coded: tuple[type[Exception], ...] = (PlanningError,),
            log_refusals: bool = False, drop: bool = False
            ) -> Callable[[zenoh.Query], None]:
    """The callback of a queryable on ``key`` that runs ``handler(query)``.

    Args:
        exact: answer only a query on ``key`` itself (a work key: a wildcard must not
            plan or move the arm), leaving any other unanswered.
        threaded: run the handler on a thread of its own (it waits: the pool, a robot).
        internal: the INTERNAL message of an unexpected failure.
        coded: the errors answered with their own code (see :func:`answering`).
        drop: finalise the query once the handler is done (the querier's stream ends
            then, not when the collector gets to it).
    """
    def handle(query: zenoh.Query) -> None:
        with answering(query, key, internal=internal, coded=coded,
                       log_refusals=log_refusals):
            handler(query)
        if drop:
            query.drop()

    def on_query(query: zenoh.Query) -> None:
        if exact and not addressed_exactly(key, query):
            return
        if threaded:
            threading.Thread(target=handle, args=(query,), daemon=True,
                             name=key.rsplit("/", 1)[-1]).start()
        else:
            handle(query)
    return on_query
