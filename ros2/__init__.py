"""Speak rmw_zenoh's wire format, so a ROS 2 workspace running ``rmw_zenoh_cpp`` sees us.

No ROS install: keys, liveliness tokens and attachments are built here from rmw_zenoh's
design document and source (each module cites the file and commit); CDR and RIHS01 type
hashes come from ``rosbags``. Layers: :mod:`.types` (CDR, hashes), :mod:`.attachment`,
:mod:`.qos`, :mod:`.names`, :mod:`.graph` (keys, tokens, GIDs), then :mod:`.topics` and
:mod:`.services` (endpoints), :mod:`.node`, :mod:`.actions` and :mod:`.joint_states`. Nothing here
imports ``clients/`` or ``service/``. Needs the ``ros2`` extra (rosbags, xxhash).
"""

from .actions import ActionClient, ActionServer, GoalHandle
from .attachment import Attachment, AttachmentLayout
from .errors import (
    EntityClosed,
    GoalAlreadyEnded,
    InvalidName,
    InvalidOption,
    InvalidTypeDefinition,
    MalformedAttachment,
    MalformedCdr,
    MalformedToken,
    MessageMismatch,
    Ros2Error,
    ServiceFailed,
    UnknownType,
)
from .joint_states import JointStates, open_joint_states
from .node import Node
from .qos import QoS
from .types import TypeStore

__all__ = [
    "ActionClient", "ActionServer", "Attachment", "AttachmentLayout", "EntityClosed",
    "GoalAlreadyEnded", "GoalHandle", "InvalidName", "InvalidOption", "InvalidTypeDefinition",
    "JointStates", "MalformedAttachment", "MalformedCdr", "MalformedToken", "MessageMismatch",
    "Node", "QoS", "Ros2Error", "ServiceFailed", "TypeStore", "UnknownType",
    "open_joint_states",
]
