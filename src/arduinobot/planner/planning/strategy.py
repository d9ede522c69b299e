"""The interface of a way of solving a motion request, and what strategies share.

:class:`arduinobot.planner.planning.pipeline.MotionPlanner` holds an ordered tuple of strategies
and hands each request to the first that :meth:`~Strategy.accepts` it. A strategy calls
only down: into the :class:`~arduinobot.planner.planning.context.PlanningContext` it is given and
into strategies it was built with (a moving start wraps the strategy that plans from
rest), never back into the planner, so no call goes round a loop.

A new way of solving (a straight line) is a class with these two methods, listed in
:func:`arduinobot.planner.planning.pipeline.default_strategies`: it accepts the goals it plans
(from rest), and wrapped in :class:`arduinobot.planner.planning.moving_start.FromMovingState` it
also serves a moving start, if blending into a motion in progress suits it.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

from arduinobot.planner.planning.motion import MotionRequest, MotionResult

if TYPE_CHECKING:  # annotations only: the context imports the heavy stack
    from arduinobot.planner.planning.context import PlanningContext

__all__ = ["Strategy", "at_rest", "moves_at_start"]


class Strategy(Protocol):
    """One way of solving a :class:`MotionRequest`.

    ``name``: what logs and errors call it.
    """

    name: str

    def accepts(self, request: MotionRequest) -> bool:
        """Whether this strategy plans ``request`` (its goal's kind, its start's state);
        decided on the request's types alone, before any check of its values."""
        ...

    def solve(self, context: PlanningContext, request: MotionRequest) -> MotionResult:
        """Plan, time and verify ``request`` with ``context``'s resources.

        Raises:
            PlanningError: each subclass for its failure (see :mod:`arduinobot.contract.errors`).
        """
        ...


def moves_at_start(request: MotionRequest) -> bool:
    """Whether ``request`` gives a start velocity or acceleration (even all zero)."""
    return request.start_velocity is not None or request.start_acceleration is not None


def at_rest(request: MotionRequest) -> MotionRequest:
    """``request`` without its start velocity and acceleration."""
    if not moves_at_start(request):
        return request
    return replace(request, start_velocity=None, start_acceleration=None)
