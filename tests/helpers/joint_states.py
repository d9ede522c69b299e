"""A recorder of the service's ``<prefix>/joint_states`` (the robot's measured state per
tick: the twin's), for the tests that check what the arm really did."""

from __future__ import annotations

import json

import numpy as np

from arduinobot.client.client import PlannerClient


class States:
    """Every ``<prefix>/joint_states`` message (the twin's measured state per tick)."""

    def __init__(self, c: PlannerClient, prefix: str = "arduinobot") -> None:
        self.msgs: list[dict] = []
        self.sub = c.session.declare_subscriber(
            f"{prefix}/joint_states", lambda s: self.msgs.append(json.loads(
                s.payload.to_bytes())))

    def arrays(self) -> tuple[list[str], np.ndarray]:
        return self.msgs[0]["name"], np.array([m["position"] for m in self.msgs])

    def close(self) -> None:
        self.sub.undeclare()
