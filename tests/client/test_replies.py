"""src/arduinobot/client/replies.py: the replies the service builds validate against
src/arduinobot/contract/schema/*_response.json and parse into the client's types; a reply that breaks the
schema is refused by the parser, naming the field, and only then."""

from __future__ import annotations

import base64
import copy
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
import zenoh

from arduinobot.cli.main import main
from arduinobot.client.client import PlannerClient
from arduinobot.client.errors import MalformedReply
from arduinobot.client.replies import CheckReply, FkReply, IkReply, PlanReply
from arduinobot.contract.zconfig import zenoh_config
from arduinobot.description import load_description
from arduinobot.service.local import LocalService
from tests.helpers.serve import free_port

ROOT = Path(__file__).resolve().parents[2]
PARSERS = {"plan": PlanReply, "fk": FkReply, "ik": IkReply, "check": CheckReply}
REQUESTS = {
    "plan": {"goal": {"named": "reach_left"}, "seed": 1, "sample_rate": 20},
    "fk": {"joints": {"joint_1": 0.5, "joint_2": 0.3}},
    "ik": {"position": [0.0, 1.0, 1.2]},
    # in collision: pairs and closest are filled
    "check": {"joints": {"joint_2": 0.3}, "obstacles": [
        {"id": "b", "shape": "box", "size": [1, 1, 1], "xyz": [0, 0.5, 1.5]}]},
}


def _validator(kind: str) -> jsonschema.Draft202012Validator:
    path = ROOT / "src/arduinobot/contract/schema" / f"{kind}_response.json"
    return jsonschema.Draft202012Validator(json.loads(path.read_text("utf-8")))


@pytest.fixture(scope="module")
def replies() -> dict[str, dict[str, Any]]:
    """One reply of each kind, built by the service's own request -> reply path."""
    local = LocalService(load_description())
    return {kind: local.request(kind, req) for kind, req in REQUESTS.items()}  # type: ignore[arg-type]


def test_service_replies_validate_and_parse(replies):
    for kind, body in replies.items():
        _validator(kind).validate(body)
    plan = PlanReply.parse(replies["plan"])
    pts = replies["plan"]["trajectory"]["points"]
    assert plan.joint_names == tuple(replies["plan"]["trajectory"]["joint_names"])
    assert plan.positions.shape == (len(pts), len(plan.joint_names))
    assert plan.efforts.tolist() == [p["effort"] for p in pts]
    assert plan.times.tolist() == [p["time_from_start"] for p in pts]
    assert plan.path.tolist() == replies["plan"]["path"]
    assert plan.verification.ok and plan.verification.certified
    assert plan.verification.min_clearance == replies["plan"]["verification"]["min_clearance"]
    assert plan.verification.closest_pair == tuple(
        replies["plan"]["verification"]["closest_pair"]) and all(plan.verification.closest_pair)
    assert plan.raw is replies["plan"] and plan.request_id == "local"
    fk = FkReply.parse(replies["fk"])
    assert fk.joints["joint_1"] == 0.5 and fk.links["claw_support"].matrix.shape == (4, 4)
    assert fk.tcp == tuple(replies["fk"]["tcp"])
    ik = IkReply.parse(replies["ik"])
    assert ik.solutions and all(s.branch and "joint_1" in s.joints for s in ik.solutions)
    check = CheckReply.parse(replies["check"])
    assert not check.valid and ("horizontal_arm", "b") in check.pairs
    assert check.joints["joint_2"] == 0.3


def _mutations(node: Any, path: tuple[str | int, ...] = ()
               ) -> Iterator[tuple[str, tuple[str | int, ...]]]:
    """Every field deleted and every value given the wrong type, into the first element
    of each list: ("delete" | "retype", path)."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield "delete", (*path, k)
            yield "retype", (*path, k)
            yield from _mutations(v, (*path, k))
    elif isinstance(node, list) and node:
        yield "retype", (*path, 0)
        yield from _mutations(node[0], (*path, 0))


def _mutated(body: dict[str, Any], how: str, path: tuple[str | int, ...]) -> dict[str, Any]:
    out = copy.deepcopy(body)
    parent = out
    for key in path[:-1]:
        parent = parent[key]
    if how == "delete":
        del parent[path[-1]]
    else:  # a string where the schema has anything else; a number for a string
        parent[path[-1]] = 1 if isinstance(parent[path[-1]], str) else "x"
    return out


def _field(path: tuple[str | int, ...]) -> str:
    return "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in path).lstrip(".")


@pytest.mark.parametrize("kind", list(PARSERS))
def test_parser_refuses_exactly_what_the_schema_refuses_naming_the_field(replies, kind):
    body, schema, parser = replies[kind], _validator(kind), PARSERS[kind]
    refused = 0
    for how, path in _mutations(body):
        bad = _mutated(body, how, path)
        valid = schema.is_valid(bad)
        try:
            parser.parse(bad)
        except MalformedReply as e:
            assert not valid, f"{how} {_field(path)}: the schema accepts what the parser refuses"
            assert e.field == _field(path) and e.details["field"] == e.field
            assert f"the {kind} reply's {e.field} " in e.message
            refused += 1
        else:
            assert valid, f"{how} {_field(path)}: the parser accepts what the schema refuses"
    assert refused >= 5  # the walk reached the required fields


def test_refusals_say_what_is_wrong(replies):
    body = replies["plan"]
    with pytest.raises(MalformedReply, match=r"plan reply's trajectory\.points\[0\]\.effort "
                                             "is missing"):
        PlanReply.parse(_mutated(body, "delete", ("trajectory", "points", 0, "effort")))
    with pytest.raises(MalformedReply, match=r"duration is invalid \(\"x\" is not of type "
                                             r"\"number\"\)"):
        PlanReply.parse(_mutated(body, "retype", ("duration",)))
    with pytest.raises(MalformedReply, match=r"check reply's \(root\) is invalid"):
        CheckReply.parse([])
    flag = copy.deepcopy(replies["check"])
    flag["valid"] = 1  # JSON's numbers are not booleans
    with pytest.raises(MalformedReply, match="valid is invalid"):
        CheckReply.parse(flag)


def test_sample_rows_hold_one_value_per_joint(replies):
    """What the schema cannot say: a row as long as joint_names."""
    short = copy.deepcopy(replies["plan"])
    short["trajectory"]["points"][1]["effort"].pop()
    _validator("plan").validate(short)
    with pytest.raises(MalformedReply, match=r"trajectory\.points\[1\]\.effort holds 3 "
                                             "values for 4 joints") as e:
        PlanReply.parse(short)
    assert e.value.field == "trajectory.points[1].effort"
    long = copy.deepcopy(replies["plan"])
    long["path"][-1].append(0.0)
    with pytest.raises(MalformedReply, match=r"path\[\d+\] holds 5 values for 4 joints"):
        PlanReply.parse(long)


@pytest.fixture
def off_contract_service() -> Iterator[str]:
    """A real zenoh peer answering fk with a reply that lacks ``links``."""
    port = free_port()
    s = zenoh.open(zenoh_config(mode="peer", listen=[f"tcp/127.0.0.1:{port}"]))
    body = json.dumps({"joints": {"joint_1": 0.0}, "request_id": "r"}).encode()
    q = s.declare_queryable("odd/fk", lambda q: q.reply("odd/fk", body), complete=True)
    yield f"tcp/127.0.0.1:{port}"
    q.undeclare()
    s.close()


def test_client_and_cli_refuse_an_off_contract_reply(off_contract_service, capsys):
    with PlannerClient(off_contract_service, prefix="odd", timeout=5) as c, \
            pytest.raises(MalformedReply) as e:
        c.fk({})
    assert e.value.field == "links" and e.value.code == "UNKNOWN"
    rc = main(["fk", "--connect", off_contract_service, "--prefix", "odd"])
    assert rc == 1
    assert "UNKNOWN: the fk reply's links is missing" in capsys.readouterr().err


def test_replies_through_a_real_service_validate_and_parse(client):
    for kind, req in REQUESTS.items():
        body = client.request(kind, req)
        _validator(kind).validate(body)
        PARSERS[kind].parse(body)
    res = client.plan(REQUESTS["plan"])
    assert isinstance(res, PlanReply) and np.all(np.diff(res.times) > 0)


def test_plan_samples_land_in_their_own_arrays(replies):
    """Each array holds its own key's rows, in order, C-contiguous; and a reply of no
    samples parses to empty arrays of the joints' width."""
    body = replies["plan"]
    pts = body["trajectory"]["points"]
    plan = PlanReply.parse(body)
    for attr, key in (("positions", "positions"), ("velocities", "velocities"),
                      ("accelerations", "accelerations"), ("efforts", "effort")):
        a = getattr(plan, attr)
        assert a.tolist() == [p[key] for p in pts], attr
        assert a.flags.c_contiguous and a.dtype == np.float64
    assert len({plan.positions[1, 0], plan.velocities[1, 0], plan.accelerations[1, 0]}) == 3
    empty = copy.deepcopy(body)
    empty["trajectory"]["points"] = []
    parsed = PlanReply.parse(empty)
    assert parsed.positions.shape == (0, len(plan.joint_names)) and parsed.times.shape == (0,)


@pytest.fixture(scope="module")
def packed(replies) -> dict[str, Any]:
    """The plan of ``replies``, asked for packed (same request, same seed)."""
    local = LocalService(load_description())
    return local.request("plan", {**REQUESTS["plan"], "trajectory_format": "packed"})


def test_a_packed_plan_parses_to_the_same_arrays_and_writes_as_points(replies, packed):
    _validator("plan").validate(packed)
    assert "points" not in packed["trajectory"]
    a, b = PlanReply.parse(replies["plan"]), PlanReply.parse(packed)
    for attr in ("times", "positions", "velocities", "accelerations", "efforts", "path"):
        assert np.array_equal(getattr(a, attr), getattr(b, attr)), attr
        assert getattr(b, attr).flags.writeable and getattr(b, attr).dtype == np.float64
    assert b.received is packed
    assert b.raw["trajectory"] == replies["plan"]["trajectory"]  # the v1 points, number for number
    assert {k: v for k, v in b.raw.items() if k != "timing"} == \
        {k: v for k, v in replies["plan"].items() if k != "timing"}


def test_a_packed_plan_off_its_contract_is_refused_naming_the_field(packed):
    def parse_with(key: str, value: Any) -> MalformedReply:
        bad = copy.deepcopy(packed)
        bad["trajectory"]["packed"][key] = value
        with pytest.raises(MalformedReply) as e:
            PlanReply.parse(bad)
        return e.value

    p = packed["trajectory"]["packed"]
    e = parse_with("velocities", "not base64!")
    assert e.field == "trajectory.packed.velocities" and "is not base64" in e.message
    short = base64.b64encode(base64.b64decode(p["effort"])[:-8]).decode()
    e = parse_with("effort", short)
    assert e.field == "trajectory.packed.effort" and "not " in e.message and "bytes" in e.message
    nan = np.frombuffer(base64.b64decode(p["time_from_start"]), "<f8").copy()
    nan[1] = np.nan
    e = parse_with("time_from_start", base64.b64encode(nan.tobytes()).decode())
    assert e.field == "trajectory.packed.time_from_start" and "not finite" in e.message
    e = parse_with("samples", p["samples"] + 1)  # every array then holds too few bytes
    assert e.field == "trajectory.packed.time_from_start"
    both = copy.deepcopy(packed)
    both["trajectory"]["points"] = []
    with pytest.raises(MalformedReply, match=r"trajectory is invalid"):
        PlanReply.parse(both)  # points or packed, never both
    for how, path in _mutations(packed["trajectory"]["packed"], ("trajectory", "packed")):
        bad = _mutated(packed, how, path)
        assert not _validator("plan").is_valid(bad)
        with pytest.raises(MalformedReply):
            PlanReply.parse(bad)


def test_the_client_asks_for_packed_plans_unless_told(client):
    res = client.plan(REQUESTS["plan"])
    assert "packed" in res.received["trajectory"] and "points" in res.raw["trajectory"]
    plain = client.plan({**REQUESTS["plan"], "trajectory_format": "points"})
    assert "points" in plain.received["trajectory"] and plain.raw is plain.received
    assert np.array_equal(res.positions, plain.positions)
