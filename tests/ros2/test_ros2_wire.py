"""The rmw_zenoh wire format, checked against rmw_zenoh's own documents and independent
implementations (no network here; tests/ros2/test_ros2_zenoh.py talks over Zenoh).

Sources (src/arduinobot/ros2/rmw_zenoh):
- docs/design.md @ 99a6a2bd10b949052f4f12c5854825dc005e95a5: the key expression and
  liveliness token examples copied verbatim below, and the attachment layout.
- rmw_zenoh_cpp/src/detail/liveliness_utils.cpp @ 3411fdec149fe0c932f24d4d79ef908eb81d7482:
  token chunks, mangling, ``qos_to_keyexpr``, the XXH3-128 GID.
- rmw_zenoh_cpp/src/detail/attachment_helpers.cpp @ 534747dca92adf15e1b1b975123037ca278db5ba:
  ``serialize_to_zbytes`` (zenoh-ext: int64, int64, std::array<uint8_t, 16>).
Independent implementations: zenoh's own zenoh-ext serialiser (the one rmw_zenoh uses),
rosbags' Jazzy typestore, and zenoh-ros2-sdk's RIHS01 code.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
import xxhash
import zenoh.ext as ze
from rosbags.typesys import Stores, get_typestore
from zenoh_ros2_sdk.utils import compute_service_type_hash, compute_type_hash_from_msg

from arduinobot.ros2 import (
    Attachment,
    InvalidName,
    InvalidOption,
    InvalidTypeDefinition,
    MalformedAttachment,
    MalformedCdr,
    MalformedToken,
    MessageMismatch,
    QoS,
    Ros2Error,
    TypeStore,
    UnknownType,
)
from arduinobot.ros2.wire.graph import (
    EndpointInfo,
    NodeInfo,
    Token,
    endpoint_token,
    gid_of,
    node_token,
    topic_key,
)
from arduinobot.ros2.wire.names import fully_qualified, validate_namespace, validate_node_name

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
ADD_TWO_INTS_HASH = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a"
TIME_MSG = "int32 sec\nuint32 nanosec\n"
HEADER_MSG = "builtin_interfaces/Time stamp\nstring frame_id\n"
JOINT_STATE_MSG = ("std_msgs/Header header\nstring[] name\nfloat64[] position\n"
                   "float64[] velocity\nfloat64[] effort\n")


@pytest.fixture(scope="module")
def types() -> TypeStore:
    t = TypeStore()
    t.register_srv("example_interfaces/srv/AddTwoInts", "int64 a\nint64 b\n---\nint64 sum\n")
    return t


# -- type hashes -------------------------------------------------------------------------
def test_message_hashes_are_rosbags_rihs01_and_design_md(types: TypeStore) -> None:
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    for name in ("sensor_msgs/msg/JointState", "trajectory_msgs/msg/JointTrajectory",
                 "action_msgs/msg/GoalStatusArray", "std_msgs/msg/String"):
        assert types.type_hash(name) == jazzy.hash_rihs01(name)
    assert types.type_hash("std_msgs/msg/String") == STRING_HASH  # design.md's chatter


def test_joint_state_hash_matches_zenoh_ros2_sdk(types: TypeStore) -> None:
    # The SDK computes RIHS01 with its own code from the .msg texts.
    sdk = compute_type_hash_from_msg(
        "sensor_msgs/msg/JointState", JOINT_STATE_MSG,
        {"std_msgs/msg/Header": HEADER_MSG, "builtin_interfaces/msg/Time": TIME_MSG})
    assert types.type_hash("sensor_msgs/msg/JointState") == sdk


def test_service_hashes_match_design_md_and_the_sdk(types: TypeStore) -> None:
    assert types.type_hash("example_interfaces/srv/AddTwoInts") == ADD_TWO_INTS_HASH
    types.register_srv("std_srvs/srv/SetBool", "bool data\n---\nbool success\nstring message")
    assert types.type_hash("std_srvs/srv/SetBool") == compute_service_type_hash(
        "std_srvs/srv/SetBool", "bool data", "bool success\nstring message")


def test_action_types_and_names(types: TypeStore) -> None:
    name = "arduinobot_msgs/action/ArduinobotTask"
    types.register_action(name, "int32 task_number\n---\nbool success\n---\nint32 percentage\n")
    assert types.kind(name) == "action"
    assert types.kind(f"{name}_SendGoal") == "srv"
    assert types.dds_name(f"{name}_SendGoal") == \
        "arduinobot_msgs::action::dds_::ArduinobotTask_SendGoal_"
    assert types.dds_name(f"{name}_FeedbackMessage") == \
        "arduinobot_msgs::action::dds_::ArduinobotTask_FeedbackMessage_"
    # the send_goal request is (goal_id, goal), as rclcpp's action server reads it
    req = types.message(f"{name}_SendGoal_Request",
                        goal_id=types.message("unique_identifier_msgs/msg/UUID",
                                              uuid=np.arange(16, dtype=np.uint8)),
                        goal=types.message(f"{name}_Goal", task_number=2))
    raw = types.serialize(req, f"{name}_SendGoal_Request")
    assert raw == bytes.fromhex("00010000") + bytes(range(16)) + struct.pack("<i", 2)
    hashes = {types.type_hash(n) for n in (name, f"{name}_SendGoal", f"{name}_GetResult",
                                           f"{name}_FeedbackMessage", f"{name}_Goal")}
    assert len(hashes) == 5 and all(h.startswith("RIHS01_") and len(h) == 71 for h in hashes)


# -- CDR -----------------------------------------------------------------------------------
def test_joint_state_cdr_decodes_with_rosbags(types: TypeStore) -> None:
    t = types
    header = t.message("std_msgs/msg/Header",
                       stamp=t.message("builtin_interfaces/msg/Time", sec=5, nanosec=7),
                       frame_id="base")
    msg = t.message("sensor_msgs/msg/JointState", header=header, name=["a", "b"],
                    position=np.array([0.5, -1.0]), velocity=np.array([]),
                    effort=np.array([]))
    raw = t.serialize(msg, "sensor_msgs/msg/JointState")
    assert raw[:4] == b"\x00\x01\x00\x00"  # CDR little-endian encapsulation, as Fast-CDR
    back = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(raw, "sensor_msgs/msg/JointState")
    assert back.header.stamp.sec == 5 and back.header.stamp.nanosec == 7
    assert back.header.frame_id == "base" and back.name == ["a", "b"]
    assert list(back.position) == [0.5, -1.0] and len(back.velocity) == 0


@pytest.mark.parametrize("raw", [b"", b"\x00\x01", b"\x00\x01\x00\x00\xff\xff\xff\x7f",
                                 b"\x07\x07\x07\x07" + bytes(40), b"\x00\x01\x00\x00" + b"\x01"])
def test_malformed_cdr_is_a_coded_error(types: TypeStore, raw: bytes) -> None:
    with pytest.raises(MalformedCdr) as e:
        types.deserialize(raw, "sensor_msgs/msg/JointState")
    assert e.value.code == "ROS2_MALFORMED_CDR" and isinstance(e.value, Ros2Error)
    assert e.value.size == len(raw)


def test_unknown_types_and_bad_definitions(types: TypeStore) -> None:
    with pytest.raises(UnknownType, match="control_msgs/action/FollowJointTrajectory"):
        types.type_hash("control_msgs/action/FollowJointTrajectory")
    with pytest.raises(UnknownType):
        types.deserialize(b"\x00\x01\x00\x00", "nope_msgs/msg/Nope")
    with pytest.raises(InvalidTypeDefinition, match="'---'"):
        types.register_srv("a_msgs/srv/A", "int32 a\n")
    with pytest.raises(InvalidTypeDefinition):
        types.register_msg("a_msgs/msg/B", "int32[ a\n")
    with pytest.raises(InvalidTypeDefinition):
        types.register_msg("a_msgs/srv/B", "int32 a\n")
    with pytest.raises(MessageMismatch):
        types.message("std_msgs/msg/String", text="no such field")
    bad = types.message("std_msgs/msg/String", data=12)
    with pytest.raises(MessageMismatch):
        types.serialize(bad, "std_msgs/msg/String")


# -- keys and liveliness tokens: design.md's examples, verbatim ---------------------------
def test_topic_keys_are_design_md_examples(types: TypeStore) -> None:
    dds = types.dds_name("std_msgs/msg/String")
    assert topic_key(0, "/chatter", dds, STRING_HASH) == \
        "0/chatter/std_msgs::msg::dds_::String_/" + STRING_HASH
    assert topic_key(0, fully_qualified("chatter", "/robot1"), dds, STRING_HASH) == \
        "0/robot1/chatter/std_msgs::msg::dds_::String_/" + STRING_HASH
    assert topic_key(2, "/add_two_ints", types.dds_name("example_interfaces/srv/AddTwoInts"),
                     types.type_hash("example_interfaces/srv/AddTwoInts")) == \
        "2/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/" + ADD_TWO_INTS_HASH


def test_liveliness_tokens_are_design_md_examples(types: TypeStore) -> None:
    listener = NodeInfo(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "/", "listener")
    assert node_token(listener) == "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    dds = types.dds_name("std_msgs/msg/String")
    sub = EndpointInfo(listener, 10, "MS", "/chatter", dds, STRING_HASH, QoS(depth=10))
    assert endpoint_token(sub) == (
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
        "std_msgs::msg::dds_::String_/" + STRING_HASH + "/::,10:,:,:,,")
    talker = NodeInfo(2, "8b20917502ee955ac4476e0266340d5c", 0, "/", "talker")
    pub = EndpointInfo(talker, 10, "MP", "/chatter", dds, STRING_HASH, QoS(depth=7))
    assert endpoint_token(pub) == (
        "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
        "std_msgs::msg::dds_::String_/" + STRING_HASH + "/::,7:,:,:,,")
    server = NodeInfo(2, "f9980ee0495eaafb3e38f0d19e2eae12", 0, "/", "add_two_ints_server")
    srv_dds = types.dds_name("example_interfaces/srv/AddTwoInts")
    ss = EndpointInfo(server, 10, "SS", "/add_two_ints", srv_dds, ADD_TWO_INTS_HASH, QoS())
    assert endpoint_token(ss) == (
        "@ros2_lv/2/f9980ee0495eaafb3e38f0d19e2eae12/0/10/SS/%/%/add_two_ints_server/"
        "%add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/" + ADD_TWO_INTS_HASH
        + "/::,10:,:,:,,")
    parsed = Token.parse(endpoint_token(ss))
    assert parsed.endpoint == ss and parsed.kind == "SS"
    assert Token.parse(node_token(listener)).node == listener


def test_namespaced_tokens_mangle_every_slash(types: TypeStore) -> None:
    node = NodeInfo(0, "ab", 3, "/arm/left", "driver")
    ep = EndpointInfo(node, 4, "MP", fully_qualified("joint_states", "/arm/left"),
                      types.dds_name("sensor_msgs/msg/JointState"),
                      types.type_hash("sensor_msgs/msg/JointState"),
                      QoS(reliability="best_effort", durability="transient_local", depth=1))
    token = endpoint_token(ep)
    assert token.startswith("@ros2_lv/0/ab/3/4/MP/%/%arm%left/driver/%arm%left%joint_states/")
    assert token.endswith("/2:1:,1:,:,:,,")
    assert Token.parse(token).endpoint == ep


@pytest.mark.parametrize("key", [
    "@ros2_lv/0/ab/0/0/NN/%/%",  # too short
    "@other/0/ab/0/0/NN/%/%/n",
    "@ros2_lv/0/ab/0/0/XX/%/%/n",
    "@ros2_lv/0/ab/0/0/MP/%/%/n",  # an endpoint kind without its topic chunks
    "@ros2_lv/x/ab/0/0/NN/%/%/n",
    "@ros2_lv/0/ab/0/1/MP/%/%/n/%t/T_/RIHS01_x/::,10:,:,",  # QoS chunk cut short
    "@ros2_lv/0/ab/0/1/MP/%/%/n/%t/T_/RIHS01_x/9::,10:,:,:,,",  # unknown reliability
])
def test_malformed_tokens_are_coded_errors(key: str) -> None:
    with pytest.raises(MalformedToken):
        Token.parse(key)


def test_qos_encoding_round_trips() -> None:
    for q in (QoS(), QoS(depth=42), QoS(history="keep_all"), QoS(deadline=(1, 500)),
              QoS(liveliness="manual_by_topic", liveliness_lease_duration=(2, 0))):
        assert QoS.decode(q.encode()) == q
    assert QoS(depth=42).encode() == "::,:,:,:,,"  # rmw_zenoh's defaults leave every field empty
    assert QoS(history="keep_all").encode() == "::2,10:,:,:,,"


def test_gid_is_xxh3_128_low_then_high_little_endian() -> None:
    token = "@ros2_lv/0/ab/0/1/MP/%/%/n/%t/T_/RIHS01_x/::,10:,:,:,,"
    h = xxhash.xxh3_128(token.encode())
    low, high = h.intdigest() & (2**64 - 1), h.intdigest() >> 64
    assert gid_of(token) == struct.pack("<QQ", low, high)
    assert gid_of(token) != gid_of(token.replace("MP", "MS"))


# -- attachments ------------------------------------------------------------------------------
GID = bytes(range(0xA0, 0xB0))


def test_attachment_current_layout_is_zenoh_ext_of_int64_int64_array() -> None:
    a = Attachment(42, 1_760_000_000_123_456_789, GID)
    raw = a.encode()
    assert raw == ze.z_serialize((ze.Int64(42), ze.Int64(1_760_000_000_123_456_789), GID)
                                 ).to_bytes()
    # design.md: 8 bytes seq LE, 8 bytes timestamp LE, 1 byte GID length (16), 16 bytes GID
    assert len(raw) == 33 and raw[16] == 16 and raw[17:] == GID
    assert struct.unpack("<qq", raw[:16]) == (42, 1_760_000_000_123_456_789)
    assert Attachment.decode(raw) == a


def test_attachment_jazzy_023_layout_has_the_key_names() -> None:
    a = Attachment(3, 99, GID)
    raw = a.encode("jazzy-0.2.3")
    assert raw == ze.z_serialize(("sequence_number", ze.Int64(3), "source_timestamp",
                                  ze.Int64(99), "source_gid", GID)).to_bytes()
    assert Attachment.decode(raw, "jazzy-0.2.3") == a
    with pytest.raises(MalformedAttachment):
        Attachment.decode(raw)  # a current-layout reader rejects it, as rmw_zenoh does
    with pytest.raises(MalformedAttachment, match="key"):
        Attachment.decode(a.encode(), "jazzy-0.2.3")


def test_an_unknown_attachment_layout_is_coded() -> None:
    with pytest.raises(InvalidOption):
        Attachment(1, 2, GID).encode("humble")  # type: ignore[arg-type]
    with pytest.raises(InvalidOption):
        Attachment.decode(Attachment(1, 2, GID).encode(), "humble")  # type: ignore[arg-type]


@pytest.mark.parametrize("raw", [None, b"", bytes(16), Attachment(1, 2, GID).encode()[:-1],
                                 Attachment(1, 2, GID).encode() + b"\0",
                                 bytes(16) + b"\x08" + bytes(8)])
def test_malformed_attachments_are_coded_errors(raw: bytes | None) -> None:
    with pytest.raises(MalformedAttachment) as e:
        Attachment.decode(raw)
    assert e.value.code == "ROS2_MALFORMED_ATTACHMENT"


# -- names ------------------------------------------------------------------------------------
def test_names() -> None:
    assert validate_namespace("") == "/" and validate_namespace("arm") == "/arm"
    assert fully_qualified("joint_states") == "/joint_states"
    assert fully_qualified("joint_states", "/a/b") == "/a/b/joint_states"
    assert fully_qualified("/abs", "/a") == "/abs"
    for bad in ("/a//b", "1abc", "a__b", "a/", "~/private", "{node}/x", "a-b", ""):
        with pytest.raises(InvalidName):
            fully_qualified(bad)
    with pytest.raises(InvalidName):
        validate_node_name("a/b")
    with pytest.raises(InvalidName):
        validate_namespace("/bad ns")
