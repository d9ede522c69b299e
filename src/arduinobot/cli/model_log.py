"""The model's warnings in the commands that only use the model: one line, not one per
warning per command (issue 38, item 9: the course's xacro warned five times before every
plan).

``check``, ``info`` and ``urdf`` print each of them themselves (they are about the model:
the log does not say them a second time), and ``serve`` logs each once when it starts;
every other command holds them, shows them with ``-v`` (at INFO), and says at its end
how many there were and where to read them.
A warning about what the user typed (``--arg NAME`` the xacro does not declare) is not
the model's and is shown as it comes.
"""

from __future__ import annotations

import logging

#: the loggers that warn about the model: its loading (URDF, xacro, SRDF, configs) and the
#: limits derived from it
MODEL_LOGGERS = ("arduinobot.description", "arduinobot.planner.kinematics.limits")
#: the commands that print the model's warnings themselves, one each
PRINTED_BY = frozenset({"check", "info", "urdf"})
#: the command whose log is its record: each warning once, as it comes
LOGGED_BY = frozenset({"serve"})


class ModelWarnings(logging.Filter):
    """A handler filter that holds the model's WARNING records: each distinct one is kept
    (and passed on at INFO when ``show``), none is emitted as a warning."""

    def __init__(self, *, show: bool) -> None:
        super().__init__()
        self.show = show
        self.held: dict[str, None] = {}  # distinct messages, in order

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno != logging.WARNING or not record.name.startswith(MODEL_LOGGERS):
            return True
        message = record.getMessage()
        if message.startswith("--arg "):  # the command line's, not the model's
            return True
        first = message not in self.held
        self.held[message] = None
        if self.show and first:
            record.levelno, record.levelname = logging.INFO, logging.getLevelName(logging.INFO)
            return True
        return False

    def summary(self, command: str) -> str | None:
        """The one line a command ends with when it held warnings, else None."""
        n = len(self.held)
        if not n:
            return None
        seen = "shown above" if self.show else "-v shows them here"
        return (f"arduinobot {command}: the model has {n} warning{'s' if n > 1 else ''} "
                f"(`arduinobot check FILE` lists them; {seen})")
