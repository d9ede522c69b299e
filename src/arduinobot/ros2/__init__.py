"""Speak rmw_zenoh's wire format, so a ROS 2 workspace running ``rmw_zenoh_cpp`` sees us.

No ROS install: keys, liveliness tokens and attachments are built here from rmw_zenoh's
design document and source (each module cites the file and commit); CDR and RIHS01 type
hashes come from ``rosbags``. Layers: ``wire/`` (the ROS 2 types' CDR and hashes, QoS,
names, the graph's tokens and GIDs, topics, services, the node), ``attachment``, then
``actions``, ``joint_states``,
``controllers``, ``control_msgs`` and ``trajectory_target`` (trajectories to
ros2_control's joint_trajectory_controllers) and ``task_server`` (the course's
/task_server action); ``pointcloud2`` (a sensor_msgs/msg/PointCloud2's points, any
fields layout), ``cloud_topic`` (a PointCloud2 topic into the kept scene, throttled) and
``camera_topic`` (a camera's latest Image and CameraInfo, for perceive); ``errors``, one
class per way the wire layer fails.
Nothing here imports ``src/arduinobot/client/`` or ``src/arduinobot/service/``. Needs the ``ros2`` extra (rosbags, xxhash).
"""

from arduinobot.ros2.actions import ActionClient, ActionServer, GoalHandle
from arduinobot.ros2.attachment import Attachment, AttachmentLayout
from arduinobot.ros2.errors import (
    ControllerFailed,
    ControllerUnavailable,
    EntityClosed,
    GoalAlreadyEnded,
    GoalRejected,
    InvalidName,
    InvalidOption,
    InvalidTypeDefinition,
    MalformedAttachment,
    MalformedCdr,
    MalformedToken,
    MessageMismatch,
    NoController,
    Ros2Error,
    ServiceFailed,
    UnknownFrame,
    UnknownType,
)
from arduinobot.ros2.joint_states import JointStates, open_joint_states
from arduinobot.ros2.task_server import TaskServer
from arduinobot.ros2.wire.node import Node
from arduinobot.ros2.wire.qos import QoS
from arduinobot.ros2.wire.types import TypeStore

__all__ = [
    "ActionClient", "ActionServer", "Attachment", "AttachmentLayout", "ControllerFailed",
    "ControllerUnavailable", "EntityClosed", "GoalAlreadyEnded", "GoalHandle", "GoalRejected",
    "InvalidName", "InvalidOption", "InvalidTypeDefinition",
    "JointStates", "MalformedAttachment", "MalformedCdr", "MalformedToken", "MessageMismatch",
    "NoController", "Node", "QoS", "Ros2Error", "ServiceFailed", "TaskServer", "TypeStore",
    "UnknownFrame", "UnknownType",
    "open_joint_states",
]
