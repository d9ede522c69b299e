"""control_msgs' FollowJointTrajectory action, registered from its upstream text.

control_msgs is not in rosbags' stores: its types are registered here from the upstream
``.msg``/``.action`` text (github.com/ros-controls/control_msgs, control_msgs/msg/
JointTolerance.msg, JointComponentTolerance.msg, action/FollowJointTrajectory.action):
branch ``jazzy`` @ f901df2662f22a39a06aa04a85a34602c47e3cc0 (release 5.8.0, what Jazzy
ships) and ``master`` @ 13dacdd8748264b6cd7cbbc9893c18c90e24be00 (6.8.0; since 6.3.0 the
feedback carries ``index`` and ``multi_dof_index``, commit b0f5dfc). The two differ in the
feedback only: the goal and result (so send_goal and get_result, and their type hashes)
are the same, so a wrong choice costs the feedback, never the motion; ``"auto"`` picks the
one whose feedback type hash the controller announces
(:func:`arduinobot.ros2.trajectory_target.detect_control_msgs`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

from arduinobot.ros2.errors import InvalidOption
from arduinobot.ros2.wire.types import TypeStore

FOLLOW_JOINT_TRAJECTORY = "control_msgs/action/FollowJointTrajectory"
ControlMsgs = Literal["auto", "jazzy", "rolling"]
CONTROL_MSGS: tuple[str, ...] = ("auto", "jazzy", "rolling")

# control_msgs/msg/JointTolerance.msg; comments dropped and, in the .action, the package
# named on JointTolerance and JointComponentTolerance (the parser resolves a bare name
# in the .action's own namespace): neither changes the type or its hash
JOINT_TOLERANCE = "string name\nfloat64 position\nfloat64 velocity\nfloat64 acceleration\n"
# control_msgs/msg/JointComponentTolerance.msg
JOINT_COMPONENT_TOLERANCE = """uint16 X_AXIS=1
uint16 Y_AXIS=2
uint16 Z_AXIS=3
uint16 TRANSLATION=4
uint16 ROTATION=5
string joint_name
uint16 component
float64 position
float64 velocity
float64 acceleration
"""
_GOAL = """trajectory_msgs/JointTrajectory trajectory
trajectory_msgs/MultiDOFJointTrajectory multi_dof_trajectory
control_msgs/JointTolerance[] path_tolerance
control_msgs/JointComponentTolerance[] component_path_tolerance
control_msgs/JointTolerance[] goal_tolerance
control_msgs/JointComponentTolerance[] component_goal_tolerance
builtin_interfaces/Duration goal_time_tolerance
"""
_RESULT = """int32 error_code
int32 SUCCESSFUL = 0
int32 INVALID_GOAL = -1
int32 INVALID_JOINTS = -2
int32 OLD_HEADER_TIMESTAMP = -3
int32 PATH_TOLERANCE_VIOLATED = -4
int32 GOAL_TOLERANCE_VIOLATED = -5
string error_string
"""
_FEEDBACK_JAZZY = """std_msgs/Header header
string[] joint_names
trajectory_msgs/JointTrajectoryPoint desired
trajectory_msgs/JointTrajectoryPoint actual
trajectory_msgs/JointTrajectoryPoint error
string[] multi_dof_joint_names
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error
"""
_FEEDBACK_ROLLING = """std_msgs/Header header
string[] joint_names
trajectory_msgs/JointTrajectoryPoint desired
trajectory_msgs/JointTrajectoryPoint actual
trajectory_msgs/JointTrajectoryPoint error
int32 index
string[] multi_dof_joint_names
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error
int32 multi_dof_index
"""
FOLLOW_JOINT_TRAJECTORY_ACTION: Mapping[str, str] = {
    v: f"{_GOAL}---\n{_RESULT}---\n{fb}"
    for v, fb in (("jazzy", _FEEDBACK_JAZZY), ("rolling", _FEEDBACK_ROLLING))}
#: FollowJointTrajectory_Result.error_code names (the .action's constants)
ERROR_CODES: Mapping[int, str] = {0: "SUCCESSFUL", -1: "INVALID_GOAL", -2: "INVALID_JOINTS",
                                  -3: "OLD_HEADER_TIMESTAMP", -4: "PATH_TOLERANCE_VIOLATED",
                                  -5: "GOAL_TOLERANCE_VIOLATED"}


def control_msgs_types(version: Literal["jazzy", "rolling"] = "jazzy") -> TypeStore:
    """A type store with control_msgs' FollowJointTrajectory (and its tolerances) of
    ``version`` registered."""
    if version not in FOLLOW_JOINT_TRAJECTORY_ACTION:
        raise InvalidOption("control_msgs", version, "jazzy or rolling")
    types = TypeStore()
    types.register_msg("control_msgs/msg/JointTolerance", JOINT_TOLERANCE)
    types.register_msg("control_msgs/msg/JointComponentTolerance", JOINT_COMPONENT_TOLERANCE)
    types.register_action(FOLLOW_JOINT_TRAJECTORY, FOLLOW_JOINT_TRAJECTORY_ACTION[version])
    return types
