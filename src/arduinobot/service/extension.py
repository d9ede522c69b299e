"""Extensions: more keys on the service's session, started once it is open
(``ServeOptions.extensions``: ``arduinobot serve`` adds ``<prefix>/execute`` and, with
``--ros2``, the ``/task_server`` action; the service itself adds ``<prefix>/task``).

An extension is a factory called with the :class:`Host` (what the service shares: its
session, its prefix, its model, its worker pool, its kept scene) that returns something
:class:`Running` (closed first on shutdown). What it uses it takes from the host: nothing
is set on it afterwards.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import zenoh

from arduinobot.description import Description
from arduinobot.service.messages import Submit, SubmitPlan

if TYPE_CHECKING:
    from arduinobot.scene.state import SceneSnapshot


@dataclass(frozen=True)
class Host:
    """What an extension is given as the service starts it.

    Attributes:
        session, prefix: the service's Zenoh session and key prefix.
        description: the robot it serves.
        submit: a job of any kind through the worker pool; submit_plan: a plan job.
        scene: the kept scene now (None before it is read): a twin takes its objects,
            a task starts in it.
    """

    session: zenoh.Session
    prefix: str
    description: Description
    submit: Submit
    submit_plan: SubmitPlan
    scene: Callable[[], SceneSnapshot | None]


class Running(Protocol):
    """A started extension: it serves its keys until closed."""

    def close(self) -> None: ...


class Extension(Protocol):
    """Starts an extension on the service's open session."""

    def __call__(self, host: Host, /) -> Running: ...
