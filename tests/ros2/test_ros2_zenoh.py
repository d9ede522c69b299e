"""Our ROS 2 endpoints over a real Zenoh session on loopback, against an independent
rmw_zenoh peer (zenoh-ros2-sdk, PyPI) and raw Zenoh.

The SDK session connects to ours (listening on tcp/127.0.0.1:<free port>, multicast
scouting off); it reads .msg texts from a directory we write (the standard definitions,
from src/arduinobot/ros2/common_interfaces), so it never fetches anything. Formats: src/arduinobot/ros2/rmw_zenoh
docs/design.md @ 99a6a2bd10b949052f4f12c5854825dc005e95a5 ("Publishers", "Service
Servers"), rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp @
3e19ec730c529035a648aec80c0ae0a056943b8c (sequence numbers from 1).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import zenoh
import zenoh_ros2_sdk as sdk
from rosbags.typesys import Stores, get_typestore
from zenoh_ros2_sdk import message_registry

from arduinobot.description.loader import load_description
from arduinobot.execution.report import Tick
from arduinobot.execution.robots.base import JointState as RobotJointState
from arduinobot.ros2 import (
    Attachment,
    EntityClosed,
    InvalidName,
    InvalidOption,
    MalformedAttachment,
    MalformedCdr,
    MessageMismatch,
    Node,
    ServiceFailed,
    TypeStore,
    UnknownType,
    open_joint_states,
)
from arduinobot.ros2.joint_states import JointStates
from arduinobot.ros2.wire.graph import Token, gid_of
from tests.helpers.serve import free_port

MSGS = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "std_msgs/msg/String": "string data\n",
    "sensor_msgs/msg/JointState": ("std_msgs/Header header\nstring[] name\nfloat64[] position\n"
                                   "float64[] velocity\nfloat64[] effort\n"),
}
ADD_TWO_INTS = ("int64 a\nint64 b", "int64 sum")


def wait_for(pred, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return pred()


@pytest.fixture
def port() -> int:
    return free_port()


@pytest.fixture
def session(port: int) -> Iterator[zenoh.Session]:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    s = zenoh.open(conf)
    yield s
    s.close()


@pytest.fixture
def peer(port: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
         session: zenoh.Session) -> Iterator[int]:
    """The SDK's process-wide session, connected to ours; yields the port it uses."""
    for name, text in MSGS.items():
        f = tmp_path / (name + ".msg")
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text)
    monkeypatch.setattr(message_registry, "_registry",
                        message_registry.MessageRegistry(str(tmp_path)))
    monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", 'scouting/multicast/enabled=false')
    yield port
    if sdk.ZenohSession._instance is not None:
        sdk.ZenohSession._instance.close()


def raw_session(port: int) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


def test_sdk_subscriber_receives_the_models_joint_states(session: zenoh.Session,
                                                         peer: int) -> None:
    robot = load_description().robot
    names = robot.actuated_joints + robot.mimic_joints
    js = open_joint_states(session, names, domain_id=7, namespace="/arm")
    try:
        got: list = []
        sub = sdk.ROS2Subscriber("/arm/joint_states", "sensor_msgs/msg/JointState", got.append,
                                 domain_id=7, router_ip="127.0.0.1", router_port=peer)
        # The SDK computed the type hash itself from the .msg texts: same key as ours.
        assert sub.keyexpr == js.publisher.key
        assert js.publisher.key.startswith("7/arm/joint_states/sensor_msgs::msg::dds_::"
                                           "JointState_/RIHS01_")
        positions = [0.1 * (i + 1) for i in range(len(names))]
        velocities = [-0.5] * len(names)
        stamp = 1_790_000_000_250_000_000
        assert wait_for(lambda: (js.publish(positions, velocities, stamp_ns=stamp)
                                 or bool(got)))
        msg = got[0]
        assert list(msg.name) == list(names) and "joint_5" in msg.name  # the mimic joint
        assert list(msg.position) == pytest.approx(positions)
        assert list(msg.velocity) == pytest.approx(velocities)
        assert len(msg.effort) == 0
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_790_000_000, 250_000_000)
        sub.close()
    finally:
        js.close()


def test_samples_carry_rmw_zenoh_attachments_and_rosbags_decodes_them(
        session: zenoh.Session, port: int) -> None:
    node = Node(session, "motion", domain_id=0)
    pub = node.create_publisher("joint_states", "sensor_msgs/msg/JointState")
    js_names = ("a", "b")
    js = JointStates(node, js_names, topic="js2")
    other = raw_session(port)
    samples: list = []
    sub = other.declare_subscriber(js.publisher.key, samples.append)
    try:
        before = time.time_ns()
        assert wait_for(lambda: (js.publish([1.0, 2.0]) or len(samples) >= 3))
        jazzy = get_typestore(Stores.ROS2_JAZZY)
        atts = [Attachment.decode(s.attachment.to_bytes()) for s in samples[:3]]
        seqs = [a.sequence_number for a in atts]
        # consecutive from the first put this subscriber saw (puts before its declaration
        # reached us are not delivered); rmw_zenoh's first put is number 1
        assert seqs == [seqs[0], seqs[0] + 1, seqs[0] + 2] and seqs[0] >= 1
        assert seqs[2] <= js.publisher.published
        assert all(a.gid == gid_of(js.publisher.token_key) for a in atts)
        assert all(before - 10**9 < a.source_timestamp < time.time_ns() + 10**9 for a in atts)
        msg = jazzy.deserialize_cdr(samples[0].payload.to_bytes(), "sensor_msgs/msg/JointState")
        assert msg.name == ["a", "b"] and list(msg.position) == [1.0, 2.0]
        # the first put is sequence number 1, as rmw_zenoh's PublisherData (a subscriber in
        # the same session sees every put from its declaration on)
        local: list = []
        local_sub = session.declare_subscriber(pub.key, local.append)
        pub.publish(jazzy.deserialize_cdr(samples[0].payload.to_bytes(),
                                          "sensor_msgs/msg/JointState"))
        assert wait_for(lambda: bool(local))
        assert Attachment.decode(local[0].attachment.to_bytes()).sequence_number == 1
        local_sub.undeclare()
    finally:
        sub.undeclare()
        other.close()
        node.close()


def test_liveliness_tokens_appear_and_go(session: zenoh.Session, port: int) -> None:
    other = raw_session(port)
    try:
        node = Node(session, "motion", namespace="/arm", domain_id=3)
        pub = node.create_publisher("joint_states", "sensor_msgs/msg/JointState")

        def tokens() -> list[str]:
            return [str(r.ok.key_expr) for r in other.liveliness().get("@ros2_lv/3/**",
                                                                       timeout=2) if r.ok]
        assert wait_for(lambda: len(tokens()) == 2)
        parsed = sorted((Token.parse(k) for k in tokens()), key=lambda t: t.kind)
        assert [t.kind for t in parsed] == ["MP", "NN"]
        mp = parsed[0].endpoint
        assert mp is not None and mp.name == "/arm/joint_states"
        assert mp.node.name == "motion" and mp.node.namespace == "/arm"
        assert mp.node.zid == str(session.info.zid())
        assert mp.qos.depth == 10 and mp.qos.reliability == "reliable"
        assert pub.token_key in tokens()
        # a token that is not rmw_zenoh's: logged and skipped by the graph query
        junk = other.liveliness().declare_token("@ros2_lv/3/not/a/graph/token")
        assert wait_for(lambda: len(tokens()) == 3)
        assert sorted(t.kind for t in node.graph()) == ["MP", "NN"]
        junk.undeclare()
        node.close()
        assert wait_for(lambda: tokens() == [])
    finally:
        other.close()


def test_our_subscription_reads_the_sdk_publisher_and_survives_junk(
        session: zenoh.Session, peer: int, port: int) -> None:
    node = Node(session, "listener", domain_id=4)
    got: list = []
    sub = node.create_subscription("chatter", "std_msgs/msg/String",
                                   lambda m, info: got.append((m.data, info)))
    other = raw_session(port)
    try:
        talker = sdk.ROS2Publisher("/chatter", "std_msgs/msg/String", domain_id=4,
                                   router_ip="127.0.0.1", router_port=peer)
        assert wait_for(lambda: (talker.publish(data="hello") or bool(got)))
        data, info = got[0]
        assert data == "hello" and len(info.publisher_gid) == 16 and info.sequence_number >= 0
        # junk on the key: no attachment, then a bad CDR body with a good attachment
        other.put(sub.key, b"\x00\x01\x00\x00garbage")
        good_att = Attachment(1, time.time_ns(), bytes(16)).encode()
        other.put(sub.key, b"\x00\x01\x00\x00\xff\xff\xff\x7f", attachment=good_att)
        assert wait_for(lambda: sub.rejected == 2)
        assert isinstance(sub.last_error, MalformedCdr)
        n = len(got)
        assert wait_for(lambda: (talker.publish(data="still here") or len(got) > n))
        assert got[-1][0] == "still here"
        talker.close()
    finally:
        other.close()
        node.close()


def test_services_with_the_sdk_client_bad_requests_and_handler_errors(
        session: zenoh.Session, peer: int, port: int) -> None:
    types = TypeStore()
    types.register_srv("example_interfaces/srv/AddTwoInts", "\n---\n".join(ADD_TWO_INTS))
    node = Node(session, "adder", domain_id=5, types=types)

    def add(req, info):
        if req.a < 0:
            raise ValueError("negative")
        return types.message("example_interfaces/srv/AddTwoInts_Response", sum=req.a + req.b)

    server = node.create_service("add_two_ints", "example_interfaces/srv/AddTwoInts", add)
    other = raw_session(port)
    try:
        client = sdk.ROS2ServiceClient("/add_two_ints", "example_interfaces/srv/AddTwoInts",
                                       request_definition=ADD_TWO_INTS[0],
                                       response_definition=ADD_TWO_INTS[1], domain_id=5,
                                       router_ip="127.0.0.1", router_port=peer, timeout=5)
        reply = None
        end = time.monotonic() + 10
        while reply is None and time.monotonic() < end:
            reply = client.call(a=2, b=40)
        assert reply is not None and reply.sum == 42
        # a request without an attachment, then one with junk CDR: coded, answered with an error
        errs = [r.err for r in other.get(server.key, payload=b"\x00\x01\x00\x00\x01",
                                         timeout=5) if r.err is not None]
        assert errs and b"ROS2_MALFORMED_ATTACHMENT" in errs[0].payload.to_bytes()
        att = Attachment(9, time.time_ns(), bytes(16)).encode()
        errs = [r.err for r in other.get(server.key, payload=b"\x00\x01", attachment=att,
                                         timeout=5) if r.err is not None]
        assert errs and b"ROS2_MALFORMED_CDR" in errs[0].payload.to_bytes()
        assert server.rejected == 2 and isinstance(server.last_error, MalformedCdr)
        # a wildcard reaching the key (a get("5/**") once started an action's goal):
        # unanswered, the handler never runs, and nothing is counted
        served = server.served
        for wild in ("5/**", server.key.rsplit("/", 1)[0] + "/*"):
            got = list(other.get(wild, payload=b"\x00\x01", attachment=att, timeout=2))
            assert got == [], wild
        assert server.rejected == 2 and server.served == served
        # our own client: a handler's exception is an error reply, and the server goes on
        ours = node.create_client("add_two_ints", "example_interfaces/srv/AddTwoInts")
        assert ours.wait_for_server(5)
        req = types.message("example_interfaces/srv/AddTwoInts_Request", a=-1, b=1)
        with pytest.raises(ServiceFailed, match="negative"):
            ours.call(req, timeout=5)
        assert server.handler_errors == 1
        req = types.message("example_interfaces/srv/AddTwoInts_Request", a=5, b=6)
        assert ours.call(req, timeout=5).sum == 11
        assert client.call(a=1, b=1).sum == 2
        client.close()
    finally:
        other.close()
        node.close()


def test_a_client_with_no_server_and_a_wrong_layout(session: zenoh.Session) -> None:
    types = TypeStore()
    types.register_srv("example_interfaces/srv/AddTwoInts", "\n---\n".join(ADD_TWO_INTS))
    node = Node(session, "lonely", domain_id=6, types=types)
    old = Node(session, "old_jazzy", domain_id=6, types=types, attachment="jazzy-0.2.3")
    try:
        client = node.create_client("nobody", "example_interfaces/srv/AddTwoInts")
        assert not client.server_ready(timeout=0.5)
        assert not client.wait_for_server(0.3)
        req = types.message("example_interfaces/srv/AddTwoInts_Request", a=1, b=2)
        with pytest.raises(ServiceFailed, match="no reply"):
            client.call(req, timeout=0.5)
        # a Jazzy 0.2.3 server cannot read a current-layout request: coded, not a crash
        calls = threading.Event()
        server = old.create_service("mixed", "example_interfaces/srv/AddTwoInts",
                                    lambda r, i: calls.set())
        with pytest.raises(ServiceFailed, match="ROS2_MALFORMED_ATTACHMENT"):
            node.create_client("mixed", "example_interfaces/srv/AddTwoInts").call(req,
                                                                                 timeout=5)
        assert isinstance(server.last_error, MalformedAttachment) and not calls.is_set()
        # the same layout on both sides works
        server2 = old.create_service("same", "example_interfaces/srv/AddTwoInts",
                                     lambda r, i: types.message(
                                         "example_interfaces/srv/AddTwoInts_Response",
                                         sum=r.a * 10 + r.b))
        assert old.create_client("same", "example_interfaces/srv/AddTwoInts").call(
            req, timeout=5).sum == 12
        assert wait_for(lambda: server2.served == 1)
    finally:
        old.close()
        node.close()


def test_publish_state_reorders_the_robots_state_and_checks_shapes(
        session: zenoh.Session) -> None:
    node = Node(session, "motion", domain_id=8)
    js = JointStates(node, ("joint_1", "joint_2", "joint_5"))
    seen: list = []
    local = session.declare_subscriber(js.publisher.key, seen.append)
    try:
        state = RobotJointState(names=("joint_5", "joint_1", "joint_2"), positions=(0.5, 0.1, 0.2),
                           velocities=(5.0, 1.0, 2.0), efforts=None, stamp=3.0)
        js.publish_state(state, stamp_ns=2_000_000_001)
        assert wait_for(lambda: bool(seen))
        msg = node.types.deserialize(seen[0].payload.to_bytes(), "sensor_msgs/msg/JointState")
        assert msg.name == ["joint_1", "joint_2", "joint_5"]
        assert list(msg.position) == [0.1, 0.2, 0.5] and list(msg.velocity) == [1.0, 2.0, 5.0]
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (2, 1)
        with pytest.raises(MessageMismatch, match="lacks joints"):
            js.publish_state(RobotJointState(("joint_1",), (0.0,), (0.0,), None, 0.0))
        with pytest.raises(MessageMismatch, match="shape"):
            js.publish([0.0, 1.0])
        with pytest.raises(MessageMismatch, match="non-finite"):
            js.publish([0.0, float("nan"), 1.0])
        assert js.publisher.published == 1
        # as an executor's per-tick callback: a tick carries the robot's state
        z = np.zeros(2)
        js(Tick(index=0, time=0.0, phase="trajectory", trajectory_time=0.0, progress=0.0,
                q=z, qd=z, qdd=z, state=state))
        assert wait_for(lambda: len(seen) == 2) and js.publisher.published == 2
    finally:
        local.undeclare()
        node.close()


def test_bad_options_are_coded(session: zenoh.Session) -> None:
    with pytest.raises(InvalidOption, match="ROS_DOMAIN_ID"):
        Node(session, "n", domain_id=300)
    with pytest.raises(InvalidOption, match="attachment"):
        Node(session, "n", attachment="humble")  # type: ignore[arg-type]
    with pytest.raises(InvalidName):
        Node(session, "bad name")
    node = Node(session, "n")
    try:
        with pytest.raises(InvalidOption, match="joint names"):
            JointStates(node, ("a", "a"))
        with pytest.raises(UnknownType):
            node.create_publisher("x", "control_msgs/msg/JointJog")
    finally:
        node.close()
    with pytest.raises(EntityClosed):
        node.create_publisher("x", "std_msgs/msg/String")
