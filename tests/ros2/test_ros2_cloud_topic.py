"""The PointCloud2 subscription of ``serve --ros2 --cloud-topic`` (arduinobot.ros2.cloud_topic)
on a real Zenoh session: only the latest cloud is taken while one is applied (nothing
queues), a frame that is no link is refused with its code and nothing applied, and each
cloud becomes a points object in its frame. The messages come from a raw Zenoh publisher
with rosbags' CDR (tests/helpers/ros2_publish.py)."""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import zenoh

from arduinobot.ros2.cloud_topic import CloudSettings, CloudTopic
from arduinobot.ros2.errors import InvalidOption
from arduinobot.ros2.wire.node import Node
from arduinobot.scene.cloud import decode_points
from tests.helpers.ros2_publish import DesignPublisher, cloud
from tests.helpers.serve import free_port
from tests.ros2.test_ros2_zenoh import raw_session, wait_for

DOMAIN = 24
LINKS = ("world", "base_link", "rgb_camera_link")


@pytest.fixture
def port() -> int:
    return free_port()


@pytest.fixture
def node(port: int) -> Iterator[Node]:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    with zenoh.open(conf) as session:
        n = Node(session, "arduinobot_motion", domain_id=DOMAIN)
        yield n
        n.close()


class Gate:
    """An apply that records each object and waits until let go."""

    def __init__(self) -> None:
        self.objects: list[dict[str, Any]] = []
        self.open = threading.Event()
        self.entered = threading.Event()

    def __call__(self, obj: dict[str, Any]) -> dict[str, Any]:
        self.objects.append(obj)
        self.entered.set()
        self.open.wait(30)
        return {"revision": len(self.objects), "clouds": {obj["id"]: {"kept": 1}}}


def test_only_the_latest_cloud_is_taken_while_one_is_applied(node, port):
    gate = Gate()
    topic = CloudTopic(node, CloudSettings("/camera/points", cloud_id="cam", rate=10.0,
                                           resolution=0.02),
                       links=LINKS, robot="arduinobot", apply=gate)
    pub_session = raw_session(port)
    try:
        pub = DesignPublisher(pub_session, DOMAIN, "/camera/points", "sensor_msgs/msg/PointCloud2")
        assert pub.key == topic.subscription.key
        first = np.array([[1.0, 2.0, 3.0]], np.float32)
        while not gate.entered.wait(0.2):  # until the route is in place
            pub.put(cloud(first, "rgb_camera_link"))
        got = topic.subscription.received
        for i in range(10):  # while the first is being applied
            pub.put(cloud(np.array([[i, i, i]], np.float32), "rgb_camera_link"))
        assert wait_for(lambda: topic.subscription.received >= got + 10, 10)
        gate.open.set()
        assert wait_for(lambda: len(gate.objects) == 2, 10)
        assert not wait_for(lambda: len(gate.objects) > 2, 1.0)  # nothing queued
        last = gate.objects[1]
        assert last["id"] == "cam" and last["frame"] == "rgb_camera_link"
        assert last["shape"] == "points" and last["resolution"] == 0.02
        np.testing.assert_array_equal(decode_points(last["points"]).points, [[9, 9, 9]])
        assert topic.applied == 2 and topic.rejected == 0
    finally:
        topic.close()
        pub_session.close()


def test_a_frame_that_is_no_link_is_refused_and_nothing_applied(node, port, caplog):
    gate = Gate()
    gate.open.set()
    topic = CloudTopic(node, CloudSettings("/camera/points", rate=10.0), links=LINKS,
                       robot="arduinobot", apply=gate)
    pub_session = raw_session(port)
    try:
        pub = DesignPublisher(pub_session, DOMAIN, "/camera/points", "sensor_msgs/msg/PointCloud2")
        pts = np.array([[1.0, 2.0, 3.0]], np.float32)
        with caplog.at_level(logging.DEBUG, logger="arduinobot.ros2.cloud_topic"):
            while topic.rejected < 3:  # until the route is in place, and again
                pub.put(cloud(pts, "camera_depth_optical_frame"))
                wait_for(lambda: topic.rejected >= 3, 0.3)
            pub.put(cloud(pts, "world"))  # and a good one still goes through
            assert wait_for(lambda: len(gate.objects) == 1, 10)
        assert gate.objects[0]["frame"] == "world" and gate.objects[0]["id"] == "cloud"
        refusals = [r for r in caplog.records if "ROS2_UNKNOWN_FRAME" in r.getMessage()]
        assert [r.levelno for r in refusals][:2] == [logging.ERROR, logging.DEBUG]
        assert "'camera_depth_optical_frame' is not a link of robot 'arduinobot'" in \
            refusals[0].getMessage()
        assert topic.last_error is not None
    finally:
        topic.close()
        pub_session.close()


def test_a_rate_out_of_range_is_refused():
    for rate in (0.0, -1.0, 11.0):
        with pytest.raises(InvalidOption):
            CloudSettings("/camera/points", rate=rate)
