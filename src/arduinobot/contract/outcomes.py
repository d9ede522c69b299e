"""How an execution ended, as its report and the wire say it.

- ``completed``: the trajectory was played to its end on a robot that reports its
  positions back (the twin, a Feetech bus).
- ``written``: played to its end on a robot that reports nothing back (the arduinobot's
  Arduino, open loop): every setpoint was written to the port; nobody saw the arm take
  them.
- ``cancelled``: stopped early on request, at rest.
- ``stopped``: stopped early, at rest, because the world changed: a scene change left
  the rest of the motion uncertified (the request's ``on_change``: ``stop``, or a
  ``replan`` that found no way on).

What an execution does when the kept scene changes while it moves is the request's
``on_change`` (:data:`ON_CHANGE`, default :data:`DEFAULT_ON_CHANGE`): ``replan`` stops
before the first uncertified piece and plans on from there to the same goal, ``stop``
stops there and reports, ``ignore`` goes on (and says so).

A client treats ``completed`` and ``written`` alike as success (:func:`succeeded`); the
word tells the user how much is known.
"""

from __future__ import annotations

from typing import Literal

Outcome = Literal["completed", "written", "cancelled", "stopped"]
SUCCEEDED: frozenset[str] = frozenset({"completed", "written"})

OnChange = Literal["replan", "stop", "ignore"]
#: an execute request's ``on_change`` values (``execute_request.json`` holds the same)
ON_CHANGE: tuple[OnChange, ...] = ("replan", "stop", "ignore")
DEFAULT_ON_CHANGE: OnChange = "replan"


def succeeded(outcome: object) -> bool:
    """Whether ``outcome`` (a report's, possibly missing) means the motion was played whole."""
    return outcome in SUCCEEDED
