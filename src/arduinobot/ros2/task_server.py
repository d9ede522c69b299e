"""The course's ``/task_server`` action (``arduinobot_msgs/action/ArduinobotTask``).

The course defines the type in its ``arduinobot_msgs`` package,
``arduinobot_msgs/action/ArduinobotTask.action`` (goal ``int32 task_number``, result
``bool success``, feedback ``int32 percentage``), and serves it as ``task_server`` from
``arduinobot_remote``'s task server node, which its task client and Alexa skill call.
The type is registered here from that .action text; rosidl names it
``arduinobot_msgs/action/ArduinobotTask`` and its services' DDS types
``arduinobot_msgs::action::dds_::ArduinobotTask_SendGoal_`` (... ``_GetResult_``,
``_FeedbackMessage_``), as :mod:`arduinobot.ros2.wire.types` makes them.

:class:`TaskServer` does the ROS 2 side only: it asks ``known(number)`` whether a task
exists (else the goal is rejected), runs it with ``run(number, on_progress, cancel)`` on a
thread of its own (``on_progress(fraction)`` becomes the feedback's percentage; ``cancel``
is set when the client cancels; it returns whether the task completed) and answers the
result. One goal at a time: a second one while one runs is rejected (``ROS2_GOAL_BUSY``,
logged by :class:`arduinobot.ros2.ActionServer`). What runs a task (``serve``'s ``<prefix>/task``) is
given by the caller: nothing here imports ``src/arduinobot/service/``.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from arduinobot.ros2.actions import ActionServer, GoalHandle
from arduinobot.ros2.wire.node import Node

log = logging.getLogger(__name__)

ARDUINOBOT_TASK = "arduinobot_msgs/action/ArduinobotTask"
ARDUINOBOT_TASK_ACTION = "int32 task_number\n---\nbool success\n---\nint32 percentage\n"

#: ``run(task_number, on_progress, cancel) -> completed``
RunTask = Callable[[int, Callable[[float], None], threading.Event], bool]


def ensure_task_type(node: Node) -> None:
    """Register ArduinobotTask in ``node.types`` (once)."""
    if ARDUINOBOT_TASK not in node.types:
        node.types.register_action(ARDUINOBOT_TASK, ARDUINOBOT_TASK_ACTION)


class TaskServer:
    """Serves ``name`` (``task_server``, in the node's namespace) of ArduinobotTask."""

    def __init__(self, node: Node, *, known: Callable[[int], bool], run: RunTask,
                 name: str = "task_server") -> None:
        ensure_task_type(node)
        self.node = node
        self._known, self._run = known, run
        self.server = ActionServer(node, name, ARDUINOBOT_TASK, self._execute,
                                   on_goal=self._on_goal, max_active=1)
        log.info("ROS 2: action %s (%s)", self.server.name, ARDUINOBOT_TASK)

    def _on_goal(self, goal: Any) -> bool:
        number = int(goal.task_number)
        try:
            ok = bool(self._known(number))
        except Exception:  # noqa: BLE001 -- a tasks.yaml that cannot be read: refuse, logged
            log.exception("%s: cannot look task %d up", self.server.name, number)
            ok = False
        if not ok:
            log.warning("ROS2_UNKNOWN_TASK: %s rejects task %d: no such task",
                        self.server.name, number)
        return ok

    def _execute(self, handle: GoalHandle) -> None:
        types = self.node.types
        number = int(handle.goal.task_number)
        last = [-1]

        def on_progress(fraction: float) -> None:
            percent = int(round(100.0 * min(max(fraction, 0.0), 1.0)))
            if percent != last[0]:  # the course's client prints each: no repeats
                last[0] = percent
                handle.publish_feedback(types.message(f"{ARDUINOBOT_TASK}_Feedback",
                                                      percentage=percent))
        try:
            completed = self._run(number, on_progress, handle.cancel_requested)
        except Exception:  # noqa: BLE001 -- logged; the client gets success false
            log.exception("%s: task %d failed", self.server.name, number)
            completed = False
        result = types.message(f"{ARDUINOBOT_TASK}_Result", success=bool(completed))
        if completed:
            handle.succeed(result)
        elif handle.cancel_requested.is_set():
            handle.canceled(result)
        else:
            handle.abort(result)
        log.info("%s: task %d %s", self.server.name, number,
                 "done" if completed else "cancelled" if handle.cancel_requested.is_set()
                 else "failed")

    def close(self, *, timeout: float = 5.0) -> None:
        """Cancel a running task (the arm stops smoothly), then withdraw the action."""
        self.server.close(timeout=timeout)
