"""``<prefix>/joint_states`` over Zenoh: sensor_msgs/JointState-shaped JSON.

Payload: ``{"stamp": s, "name": [...], "position": [rad], "velocity": [rad/s],
"effort": [N m] | null, "phase": "move_to_start" | "trajectory" | "stop",
"progress": 0..1}`` — the actuated joints then the mimic joints.
"""

from __future__ import annotations

import json
from typing import Any

from arduinobot.contract.wire import JSON
from arduinobot.execution.report import Tick


def tick_message(tick: Tick) -> dict[str, Any]:
    return {**tick.state.to_dict(), "phase": tick.phase, "progress": tick.progress}


class JointStatePublisher:
    """Publishes each tick's state on ``<prefix>/joint_states`` through ``session``."""

    def __init__(self, session: Any, prefix: str) -> None:
        self.key = f"{prefix}/joint_states"
        self._pub = session.declare_publisher(self.key, encoding=JSON)

    def __call__(self, tick: Tick) -> None:
        self._pub.put(json.dumps(tick_message(tick)).encode())
