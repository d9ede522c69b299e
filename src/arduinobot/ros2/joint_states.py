"""``/joint_states``: ``sensor_msgs/msg/JointState`` for robot_state_publisher and RViz.

:func:`open_joint_states` is what ``serve --ros2`` wires in: a node on the service's
Zenoh session with one publisher; call it with each execution tick (or call
:meth:`JointStates.publish` / :meth:`JointStates.publish_state`) at the execution rate. One
publish costs about 0.1 ms (rosbags' serialiser), well inside a control tick.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from arduinobot.ros2.attachment import AttachmentLayout
from arduinobot.ros2.errors import InvalidOption, MessageMismatch
from arduinobot.ros2.wire.node import Node
from arduinobot.ros2.wire.qos import QoS

if TYPE_CHECKING:
    import zenoh

JOINT_STATE = "sensor_msgs/msg/JointState"
#: What joint_state_publisher and ros2_control's joint_state_broadcaster publish with.
JOINT_STATES_QOS = QoS(depth=10)


class JointStates:
    """Publishes the model's joints (actuated, then mimic) on ``joint_states``.

    ``names`` fixes the order; :meth:`publish` takes arrays in that order.
    """

    def __init__(self, node: Node, names: Sequence[str], *, topic: str = "joint_states",
                 frame_id: str = "", owns_node: bool = False) -> None:
        if not names or len(set(names)) != len(names):
            raise InvalidOption("joint names", list(names), "unique and at least one")
        self.node, self.names, self.frame_id = node, tuple(names), frame_id
        self.publisher = node.create_publisher(topic, JOINT_STATE, qos=JOINT_STATES_QOS)
        self._types = node.types
        self._owns_node = owns_node

    def message(self, positions: Sequence[float], velocities: Sequence[float] | None = None,
                efforts: Sequence[float] | None = None, *, stamp_ns: int | None = None) -> Any:
        """The JointState message; ``stamp_ns`` [ns since the UNIX epoch] defaults to now
        (ROS time: RViz and tf want wall-clock stamps, not the robot's own clock)."""
        import numpy as np

        n = len(self.names)
        arrays = {}
        for field, values in (("position", positions), ("velocity", velocities),
                              ("effort", efforts)):
            a = np.asarray([] if values is None else values, dtype=np.float64)
            if a.shape not in ((n,), (0,)) or (field == "position" and a.shape != (n,)):
                raise MessageMismatch(JOINT_STATE, f"{field} has shape {a.shape}, want ({n},)"
                                      + ("" if field == "position" else " or empty"))
            if not np.all(np.isfinite(a)):
                raise MessageMismatch(JOINT_STATE, f"{field} has a non-finite value")
            arrays[field] = a
        ns = time.time_ns() if stamp_ns is None else int(stamp_ns)
        t = self._types
        stamp = t.message("builtin_interfaces/msg/Time", sec=ns // 1_000_000_000,
                          nanosec=ns % 1_000_000_000)
        header = t.message("std_msgs/msg/Header", stamp=stamp, frame_id=self.frame_id)
        return t.message(JOINT_STATE, header=header, name=list(self.names), **arrays)

    def publish(self, positions: Sequence[float], velocities: Sequence[float] | None = None,
                efforts: Sequence[float] | None = None, *, stamp_ns: int | None = None) -> None:
        """Publish positions [rad], velocities [rad/s] and efforts [N m] (both optional,
        sent empty when None), each in :attr:`names` order."""
        self.publisher.publish(self.message(positions, velocities, efforts,
                                            stamp_ns=stamp_ns))

    def publish_state(self, state: Any, *, stamp_ns: int | None = None) -> None:
        """Publish a robot state with ``names``, ``positions``, ``velocities`` and
        ``efforts`` (clients.robots.base.JointState), reordered to :attr:`names`."""
        index = {n: i for i, n in enumerate(state.names)}
        missing = [n for n in self.names if n not in index]
        if missing:
            raise MessageMismatch(JOINT_STATE, f"the state lacks joints {missing}")
        order = [index[n] for n in self.names]
        efforts = None if state.efforts is None else [state.efforts[i] for i in order]
        self.publish([state.positions[i] for i in order],
                     [state.velocities[i] for i in order], efforts, stamp_ns=stamp_ns)

    def __call__(self, tick: Any) -> None:
        """An executor's per-tick callback (as src/arduinobot/client/joint_states.py's
        ``JointStatePublisher``): publishes ``tick.state``, stamped now."""
        self.publish_state(tick.state)

    def close(self) -> None:
        self.publisher.close()
        if self._owns_node:
            self.node.close()


def open_joint_states(session: zenoh.Session, names: Sequence[str], *, domain_id: int = 0,
                      namespace: str = "/", node_name: str = "arduinobot_motion",
                      attachment: AttachmentLayout = "current") -> JointStates:
    """A node ``node_name`` with a ``joint_states`` publisher of ``names`` (the model's
    ``robot.actuated_joints + robot.mimic_joints``); ``close()`` closes both."""
    node = Node(session, node_name, namespace=namespace, domain_id=domain_id,
                attachment=attachment)
    try:
        return JointStates(node, names, owns_node=True)
    except BaseException:
        node.close()
        raise
