"""``arduinobot serve --ros2`` (issue 31, item 1): /joint_states at the execution rate
while the twin moves, as an independent rmw_zenoh peer (zenoh-ros2-sdk, PyPI) sees it.

The SDK subscribes with the type hash it computes from the .msg texts (written to a
folder here, as tests/ros2/test_ros2_zenoh.py does), so a key or attachment of ours that
rmw_zenoh's format would not accept never reaches its callback. Formats: src/arduinobot/ros2/rmw_zenoh
docs/design.md @ 99a6a2bd10b949052f4f12c5854825dc005e95a5 ("Topic and Service name
mapping to Zenoh key expressions", "Graph Cache").
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh
import zenoh_ros2_sdk as sdk
from zenoh_ros2_sdk import message_registry

from arduinobot.client.client import PlannerClient
from arduinobot.description import load_description
from arduinobot.ros2.wire.graph import Token, query_graph
from tests.helpers.serve import free_port, start_server
from tests.ros2.test_ros2_zenoh import MSGS, wait_for

DOMAIN = 5


@pytest.fixture(scope="module")
def served() -> Iterator[tuple]:
    port = free_port()
    srv = start_server(["--workers", "1", "--ros2", "--ros-domain-id", str(DOMAIN),
                        "--ros-namespace", "/cell"], port=port)
    yield srv, port
    srv.stop()


@pytest.fixture
def sdk_registry(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    for name, text in MSGS.items():
        f = tmp_path / (name + ".msg")
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text)
    monkeypatch.setattr(message_registry, "_registry",
                        message_registry.MessageRegistry(str(tmp_path)))
    monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", "scouting/multicast/enabled=false")
    yield
    if sdk.ZenohSession._instance is not None:
        sdk.ZenohSession._instance.close()


@pytest.mark.slow
def test_serve_ros2_publishes_joint_states_while_the_twin_moves(served, sdk_registry
                                                                ) -> None:
    srv, port = served
    robot = load_description().robot
    names = list(robot.actuated_joints + robot.mimic_joints)
    got: list = []
    arrived: list[float] = []

    def on_msg(msg) -> None:
        got.append(msg)
        arrived.append(time.monotonic())
    sub = sdk.ROS2Subscriber("/cell/joint_states", "sensor_msgs/msg/JointState", on_msg,
                             domain_id=DOMAIN, router_ip="127.0.0.1", router_port=port)
    endpoint = f"tcp/127.0.0.1:{port}"
    try:
        # the node and its publisher are on the graph before anything moves
        with zenoh.open(_client_config(endpoint)) as z:
            tokens = query_graph(z, f"@ros2_lv/{DOMAIN}/**")
        kinds = {(t.kind, t.node.name, t.node.namespace,
                  t.endpoint.name if t.endpoint else None) for t in tokens}
        assert ("NN", "arduinobot_motion", "/cell", None) in kinds
        assert ("MP", "arduinobot_motion", "/cell", "/cell/joint_states") in kinds
        pub = next(t for t in tokens if t.kind == "MP" and t.endpoint
                   and t.endpoint.name == "/cell/joint_states")
        assert isinstance(pub, Token) and pub.endpoint.type_hash in sub.keyexpr
        time.sleep(0.3)  # the SDK's subscriber reaches the service
        assert got == []  # nothing moves: nothing published
        with PlannerClient([endpoint], timeout=60.0) as c:
            t0 = time.monotonic()
            done = c.execute(plan={"goal": {"named": "reach_left"}})
            t1 = time.monotonic()
        report = dict(done.report or {})
        assert report["outcome"] == "completed"
        assert wait_for(lambda: got and arrived[-1] < time.monotonic() - 0.2, 5.0)
    finally:
        sub.close()
    during = [m for m, t in zip(got, arrived) if t0 <= t <= t1 + 0.5]
    assert len(during) == len(got)
    # the execution rate (100 Hz): one message per tick, a few lost to the start-up at most
    assert len(got) >= 0.9 * report["ticks"] and len(got) <= report["ticks"]
    assert all(list(m.name) == names for m in got) and "joint_5" in names
    last = got[-1]
    goal = next(s for s in load_description().srdf.states if s.name == "reach_left")
    for j, q in goal.values.items():
        assert last.position[names.index(j)] == pytest.approx(q, abs=0.02)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in got]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert abs(stamps[-1] - time.time()) < 30  # wall clock, as tf and RViz want
    assert any(abs(v) > 0.05 for m in got for v in m.velocity)


def _client_config(endpoint: str) -> zenoh.Config:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return conf
