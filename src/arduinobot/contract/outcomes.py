"""How an execution ended, as its report and the wire say it.

- ``completed``: the trajectory was played to its end on a robot that reports its
  positions back (the twin, a Feetech bus).
- ``written``: played to its end on a robot that reports nothing back (the arduinobot's
  Arduino, open loop): every setpoint was written to the port; nobody saw the arm take
  them.
- ``cancelled``: stopped early on request, at rest.

A client treats ``completed`` and ``written`` alike as success (:func:`succeeded`); the
word tells the user how much is known.
"""

from __future__ import annotations

from typing import Literal

Outcome = Literal["completed", "written", "cancelled"]
SUCCEEDED: frozenset[str] = frozenset({"completed", "written"})


def succeeded(outcome: object) -> bool:
    """Whether ``outcome`` (a report's, possibly missing) means the motion was played whole."""
    return outcome in SUCCEEDED
