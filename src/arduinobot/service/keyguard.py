"""Queryables that answer only a query naming their key exactly.

Zenoh routes a query to every queryable whose key its key expression intersects:
``arduinobot/*``, ``arduinobot/**`` and ``arduinobot/pl$*`` all reach ``arduinobot/plan``.
An access-control rule, though, applies to a query only when the rule's key expression
includes the query's: a rule denying ``arduinobot/plan`` does not cover those wildcards,
which then reach the plan queryable past it (issue 13). A queryable that does work or
moves the arm therefore answers exact queries only, whatever the router's config, and one
wildcard query cannot fan out into a job per work key per instance.
"""

from __future__ import annotations

import logging

import zenoh

_log = logging.getLogger(__name__)


def addressed_exactly(key: str, query: zenoh.Query) -> bool:
    """True if ``query``'s key expression is ``key`` itself (no wildcard, no ``$*``).

    A False query is left unanswered: dropping it ends it for the querier, who sees no
    reply from this key, exactly as if the key were hidden by access control.
    """
    asked = str(query.key_expr)
    if asked == key:
        return True
    _log.debug("%s: not answering a query on '%s' (only '%s' itself)", key, asked, key)
    return False
