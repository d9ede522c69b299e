"""src/arduinobot/service/local.py: `--local` answers through the service's own request ->
reply path, without Zenoh, the server or the pool (that no client imports the server's
internals is a row of tests/test_layers.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest

from arduinobot.contract.codes import Code
from arduinobot.contract.errors import InvalidRequest, JointLimitViolation
from arduinobot.description import load_description
from arduinobot.service.local import LOCAL_REQUEST_ID, LocalService

ROOT = Path(__file__).resolve().parents[2]
# the modules a --local command must not load: the server, its pool and Zenoh
SERVER_SIDE = ("zenoh", "arduinobot.service.server", "arduinobot.service.process.pool", "arduinobot.service.process.worker", "arduinobot.service.process.zygote")


@pytest.fixture(scope="module")
def local() -> LocalService:
    return LocalService(load_description())


def _schema(name: str) -> dict:
    return json.loads((ROOT / "src/arduinobot/contract/schema" / f"{name}.json").read_text("utf-8"))


def test_fk_reply_is_the_services_and_validates(local: LocalService) -> None:
    body = local.request("fk", {"joints": {"joint_1": 0.5}})
    jsonschema.validate(body, _schema("fk_response"))
    assert body["request_id"] == LOCAL_REQUEST_ID
    assert body["joints"]["joint_1"] == 0.5


def test_bad_requests_raise_the_services_coded_errors(local: LocalService) -> None:
    with pytest.raises(InvalidRequest) as e:  # the schema's check, as in a worker
        local.request("fk", {"joints": {"joint_1": 0.5}, "bogus": 1})
    assert e.value.code is Code.INVALID_REQUEST
    with pytest.raises(JointLimitViolation) as lim:  # the robot's check, as in a worker
        local.request("check", {"joints": {"joint_2": 99.0}})
    assert lim.value.details["field"] == "joints.joint_2"
    with pytest.raises(InvalidRequest) as kind:  # no key of the service answers it
        local.request("move", {})  # type: ignore[arg-type]
    assert kind.value.details["field"] == "kind"


def test_the_description_reply_limits_every_actuated_joint(local: LocalService) -> None:
    desc = local.description()
    assert set(desc["limits"]) == set(desc["actuated_joints"])
    assert {k for lim in desc["limits"].values() for k in lim} == {
        "lower", "upper", "velocity", "acceleration", "jerk", "effort"}


def test_local_cli_loads_neither_zenoh_nor_the_server() -> None:
    code = (
        "import sys, io, contextlib\n"
        "from arduinobot.cli.main import main\n"
        "out = io.StringIO()\n"
        "with contextlib.redirect_stdout(out):\n"
        "    rc = main(['fk', '--local', '--joints', '0.1,0.2', '--json'])\n"
        "assert rc == 0, rc\n"
        "import json; assert json.loads(out.getvalue())['request_id'] == 'local'\n"
        f"print(sorted(m for m in {SERVER_SIDE!r} if m in sys.modules))\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "[]"
