"""`arduinobot serve` as a real process, queried with the client and with raw zenoh gets."""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest
import zenoh

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.contract import wire
from arduinobot.contract.zconfig import zenoh_config
from tests.helpers.planning_scenes import SPLIT_GOAL, SPLIT_START, split_dicts


@pytest.fixture(scope="module")
def raw(server):
    """A plain zenoh client session (multicast scouting off) to the server."""
    s = zenoh.open(zenoh_config(mode="client", connect=[server.endpoint], listen=[]))
    yield s
    s.close()


def raw_get(session, key: str, payload: bytes | None) -> zenoh.Reply:
    replies = list(session.get(key, payload=payload, timeout=30.0))
    assert len(replies) == 1
    return replies[0]


def raw_error(session, payload: bytes, key: str = "arduinobot/plan") -> dict:
    r = raw_get(session, key, payload)
    assert r.err is not None, r.ok and r.ok.payload.to_string()
    assert str(r.err.encoding).startswith("application/json")
    body = json.loads(r.err.payload.to_bytes())
    assert set(body["error"]) == {"code", "message", "details"}
    return body["error"]


def test_ready_line_names_the_keys(server):
    for kind in ("plan", "fk", "ik", "check", "description", "health", "schema"):
        assert f"arduinobot/{kind}" in server.ready_line
    assert f"arduinobot/alive/{server.instance}" in server.ready_line


def test_plan_over_raw_zenoh_get(raw):
    req = {"goal": {"named": "reach_forward"}, "seed": 3}
    r = raw_get(raw, "arduinobot/plan", json.dumps(req).encode())
    assert r.ok is not None
    assert str(r.ok.encoding).startswith("application/json")
    body = json.loads(r.ok.payload.to_bytes())
    jsonschema_validate("plan_response", body)
    names = body["trajectory"]["joint_names"]
    assert names == ["joint_1", "joint_2", "joint_3", "joint_4"]
    first, last = body["trajectory"]["points"][0], body["trajectory"]["points"][-1]
    assert first["positions"] == pytest.approx([0, 0, 0, 0], abs=1e-9)
    assert last["positions"] == pytest.approx([0, 0.8, 0.6, 0], abs=1e-6)
    assert last["time_from_start"] == pytest.approx(body["duration"])
    assert all(len(w) == 4 for w in body["path"])
    assert body["path"][0] == pytest.approx([0, 0, 0, 0]) and \
        body["path"][-1] == pytest.approx([0, 0.8, 0.6, 0])
    assert body["verification"]["ok"] is True
    assert body["request_id"]


def jsonschema_validate(name: str, body: dict) -> None:
    import jsonschema
    jsonschema.validate(body, wire.schema(name))


def test_plan_with_the_client_gives_typed_results(client):
    res = client.plan(start={"joint_1": 0.2}, goal={"joints": {"joint_1": -0.4, "joint_3": 0.3}},
                      sample_rate=50, seed=1)
    assert res.joint_names == ("joint_1", "joint_2", "joint_3", "joint_4")
    assert res.positions.shape == (len(res.times), 4)
    assert res.positions[0] == pytest.approx([0.2, 0, 0, 0])
    assert res.positions[-1] == pytest.approx([-0.4, 0, 0.3, 0], abs=1e-6)
    assert np.diff(res.times)[:-1] == pytest.approx(1 / 50)  # 50 Hz, exact final sample
    assert res.path.shape[1] == 4 and "total" in res.timing


def test_plan_to_a_position_reaches_it(client):
    target = [0.0, 1.0, 1.2]
    res = client.plan(goal={"position": target}, seed=2)
    fk = client.fk(dict(zip(res.joint_names, res.positions[-1])))
    assert np.linalg.norm(np.subtract(fk.tcp, target)) < 1e-6  # the IK tests' tolerance


def _box(id_="box", size=(1, 1, 1), xyz=(0, 0.5, 1.5)):
    return {"id": id_, "shape": "box", "size": list(size), "xyz": list(xyz)}


@pytest.mark.parametrize("payload, code, field", [
    (b'{"goal": {"named": "home"', "INVALID_REQUEST", None),                   # malformed
    (b'["goal"]', "INVALID_REQUEST", "(root)"),                                # wrong type
    (b'{"goal": {"joints": {"joint_1": "0.3"}}}', "INVALID_REQUEST", "goal.joints.joint_1"),
    (b'{"goal": {"named": "home"}, "colour": "red"}', "INVALID_REQUEST", "colour"),
    (b'{"goal": {"joints": {"wrist": 0.3}}}', "INVALID_REQUEST", "goal.joints.wrist"),
    (b'{"goal": {"joints": {"joint_5": 0.3}}}', "INVALID_REQUEST", "goal.joints.joint_5"),
    (b'{"goal": {"named": "home"}, "start": {"joint_2": NaN}}', "INVALID_REQUEST", None),
    (b'{"goal": {"named": "home"}, "start": {"joint_2": Infinity}}', "INVALID_REQUEST", None),
    (b'{"goal": {"named": "home"}, "start": {"joint_2": 1e400}}', "INVALID_REQUEST",
     "start.joint_2"),
    (b'{"goal": {"joints": {"joint_1": 2.0}}}', "INVALID_REQUEST", "goal.joints.joint_1"),
    (b'{"goal": {"named": "home"}, "sample_rate": 5000}', "INVALID_REQUEST", "sample_rate"),
    (b'{"goal": {"named": "nowhere"}}', "INVALID_REQUEST", "goal.named"),
    (b'{"goal": {"named": "home"}, "planner": "Teleport"}', "INVALID_REQUEST", "planner"),
    (json.dumps({"goal": {"named": "home"}, "obstacles": [_box()]}).encode(),
     "START_IN_COLLISION", None),
    (json.dumps({"goal": {"named": "reach_forward"},
                 "obstacles": [_box("goalbox", (0.3, 0.3, 0.3), (-0.15, -0.18, 2.57))]}).encode(),
     "GOAL_IN_COLLISION", None),
    (b'{"goal": {"position": [0, 5, 0]}}', "GOAL_OUT_OF_REACH", None),
    (json.dumps({"goal": {"joints": SPLIT_GOAL}, "start": SPLIT_START,  # free, unreachable
                 "obstacles": split_dicts(), "planning_time": 0.2, "seed": 1,
                 "ground": False}).encode(),
     "NO_PATH_FOUND", None),
    (b'{"goal": {"named": "home"}, "planner": "' + b"x" * (300 * 1024) + b'"}',
     "INVALID_REQUEST", None),
])
def test_each_bad_request_gets_its_code_and_the_service_keeps_serving(raw, payload, code,
                                                                       field):
    err = raw_error(raw, payload)
    assert err["code"] == code, err
    if field is not None:
        assert err["details"]["field"] == field, err
    assert err["details"]["request_id"]
    r = raw_get(raw, "arduinobot/fk", b'{"joints": {"joint_1": 0.1}}')
    assert r.ok is not None


def test_mimic_error_names_the_leader(raw):
    err = raw_error(raw, b'{"goal": {"named": "home"}, "start": {"joint_5": 0.1}}')
    assert err["details"]["leader"] == "joint_4" and "joint_4" in err["message"]


def test_payload_cap_error_says_the_limit(raw):
    err = raw_error(raw, b" " * (wire.MAX_PAYLOAD + 1))
    assert err["details"]["limit"] == wire.MAX_PAYLOAD


def test_client_raises_one_class_per_code(client):
    with pytest.raises(errors.StartInCollision) as e:
        client.plan(goal={"named": "home"}, obstacles=[_box()])
    assert ["forward_drive_arm", "box"] in e.value.details["pairs"]
    with pytest.raises(errors.GoalOutOfReach):
        client.plan(goal={"position": [0, 5, 0]})
    with pytest.raises(errors.NoPathFound) as e:
        client.plan(goal={"joints": SPLIT_GOAL}, start=SPLIT_START, obstacles=split_dicts(),
                    planning_time=0.2, seed=1, ground=False)
    assert e.value.code == "NO_PATH_FOUND" and "found no path" in e.value.message
    with pytest.raises(errors.InvalidRequest):
        client.plan(goal={"named": "home"}, velocity_scaling=0)


def test_fk_ik_and_check(client):
    fk = client.fk({"joint_1": 0.5}, links=["base_plate"])
    assert list(fk.links) == ["base_plate"]
    assert fk.links["base_plate"].rpy[2] == pytest.approx(0.5)
    assert fk.links["base_plate"].matrix.shape == (4, 4)
    sols = client.ik([0.0, 1.0, 1.2]).solutions
    assert sols
    for s in sols:
        assert np.linalg.norm(np.subtract(client.fk(s.joints).tcp, [0.0, 1.0, 1.2])) < 1e-6
    free = client.check_state({"joint_2": 0.3})
    assert free.valid and free.pairs == () and free.clearance > 0
    hit = client.check_state({"joint_2": 0.3}, obstacles=[_box()])
    assert not hit.valid and ("horizontal_arm", "box") in hit.pairs
    with pytest.raises(errors.InvalidRequest):
        client.check_state({"joint_5": 0.1})
    with pytest.raises(errors.GoalOutOfReach):
        client.ik([0, 5, 0])


def test_health_description_and_schema(client, server):
    h = client.health()
    assert h["instance"] == server.instance and len(h["workers"]) == 2
    assert all(w["pid"] for w in h["workers"])
    assert h["counters"]["received"] >= 1 and h["uptime"] > 0 and "queue_depth" in h
    d = client.description()
    assert d["actuated_joints"] == ["joint_1", "joint_2", "joint_3", "joint_4"]
    assert d["mimic_joints"]["joint_5"]["leader"] == "joint_4"
    assert "<robot" in d["urdf"] and "<group" in d["srdf"]
    assert d["limits"]["joint_2"]["effort"] == pytest.approx(30.0)
    s = client.schema()
    assert s["plan_request"] == wire.schema("plan_request")


def test_instances_are_discovered_and_addressable(client, server):
    assert client.instances(refresh=True) == (server.instance,)
    h = client.health(instance=server.instance)
    assert h["instance"] == server.instance


def test_wrong_prefix_is_no_route(server):
    with PlannerClient(server.endpoint, prefix="nobody", timeout=5) as c, \
            pytest.raises(errors.ServiceUnavailable) as e:
        c.health()
    assert e.value.reason == "no_route" and "arduinobot serve" in e.value.message


PILLARS = [{"id": "p1", "shape": "box", "size": [0.12, 0.12, 2.0], "xyz": [0.5, 0.8, 1.0]},
           {"id": "p2", "shape": "box", "size": [0.12, 0.12, 2.0], "xyz": [-0.5, 0.8, 1.0]},
           {"id": "beam", "shape": "box", "size": [1.2, 0.12, 0.12], "xyz": [0, 0.8, 2.0]}]


def test_same_request_and_seed_give_the_same_trajectory_in_any_worker_and_order(client):
    # the goal reaches under the base's plane: no ground (this test is about determinism)
    detour = {"start": {"joint_1": 0.137, "joint_2": 1.367, "joint_3": 0.992},
              "goal": {"joints": {"joint_1": 1.123, "joint_2": -1.465, "joint_3": 0.721}},
              "obstacles": PILLARS, "ground": False}
    other = {"start": {"joint_1": -0.4}, "goal": {"named": "reach_left"}, "obstacles": PILLARS}
    first = client.plan(detour, seed=3)
    assert first.planner == "RRTConnect"  # OMPL's random search, not the straight line
    # the same request again, after other seeds, and concurrently on both workers
    client.plan(other, seed=8)
    client.plan(detour, seed=4)
    results: list = [None] * 4

    def run(i: int) -> None:
        results[i] = client.plan(detour, seed=3)
    threads = [threading.Thread(target=run, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    for r in [client.plan(detour, seed=3), *results]:
        assert r is not None
        assert np.array_equal(r.path, first.path)
        assert np.array_equal(r.positions, first.positions)
