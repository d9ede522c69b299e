"""The service's one queryable guard and one error replier (service/queries.py), on real
Zenoh sessions: a coded error answers as itself, anything else INTERNAL, a wildcard
gets no reply from an exact key, a threaded handler runs off Zenoh's thread; and the
wings use it (one guard, one replier, one JSON constant: issue 37)."""

from __future__ import annotations

import re
import threading
from collections.abc import Iterator
from pathlib import Path

import orjson
import pytest
import zenoh

from arduinobot.client.codec import decode_reply
from arduinobot.client.errors import InternalError, InvalidRequest, ServiceError
from arduinobot.contract import wire
from arduinobot.contract.errors import InvalidRequest as Refused
from arduinobot.contract.zconfig import zenoh_config
from arduinobot.service.queries import guarded
from tests.helpers.serve import free_port

SRC = Path(__file__).resolve().parents[2] / "src/arduinobot"


@pytest.fixture
def sessions() -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    ep = f"tcp/127.0.0.1:{free_port()}"
    with zenoh.open(zenoh_config(mode="peer", listen=[ep], connect=[])) as server, \
            zenoh.open(zenoh_config(mode="client", connect=[ep], listen=[])) as client:
        yield server, client


def _ask(client: zenoh.Session, key: str) -> list[zenoh.Reply]:
    return list(client.get(key, payload=b"{}", timeout=10.0))


def _decoded(client: zenoh.Session, key: str) -> dict:
    replies = _ask(client, key)
    assert len(replies) == 1
    return decode_reply(replies[0], key, 10.0)


def test_a_coded_error_answers_as_itself_and_a_bug_as_internal(sessions) -> None:
    server, client = sessions

    def refuse(query: zenoh.Query) -> None:
        raise Refused("bad goal", field="goal.named")

    def crash(query: zenoh.Query) -> None:
        raise KeyError("oops")

    def fine(query: zenoh.Query) -> None:
        query.reply(query.key_expr, wire.encode({"ok": True}), encoding=wire.JSON)
    held = [server.declare_queryable(k, guarded(k, h, exact=True), complete=True)
            for k, h in (("t/refuse", refuse), ("t/crash", crash), ("t/fine", fine))]
    held.append(server.declare_queryable(
        "t/crash_named", guarded("t/crash_named", crash, exact=True, internal=None),
        complete=True))
    with pytest.raises(InvalidRequest) as e:
        _decoded(client, "t/refuse")
    assert e.value.details["field"] == "goal.named" and e.value.message.endswith("bad goal")
    with pytest.raises(InternalError) as bug:
        _decoded(client, "t/crash")
    assert bug.value.message == "unexpected failure in the service"
    with pytest.raises(InternalError) as named:  # internal=None: the exception's text
        _decoded(client, "t/crash_named")
    assert named.value.details["exception"] == "KeyError" and "oops" in named.value.message
    assert _decoded(client, "t/fine") == {"ok": True}
    for q in held:
        q.undeclare()


def test_an_exact_key_leaves_a_wildcard_unanswered_and_threads_when_asked(sessions) -> None:
    server, client = sessions
    threads: list[str] = []

    def noting(key: str):
        def note(query: zenoh.Query) -> None:
            threads.append(threading.current_thread().name)
            query.reply(key, b'{"ok": true}', encoding=wire.JSON)
        return note
    q1 = server.declare_queryable("w/exact", guarded("w/exact", noting("w/exact"),
                                                     exact=True, threaded=True),
                                  complete=True)
    q2 = server.declare_queryable("w/open", guarded("w/open", noting("w/open"), exact=False),
                                  complete=True)
    got = {str(r.ok.key_expr) for r in _ask(client, "w/*") if r.ok is not None}
    assert got == {"w/open"}  # the exact key did not answer the wildcard
    assert orjson.loads(_ask(client, "w/exact")[0].ok.payload.to_bytes()) == {"ok": True}
    assert "exact" in threads  # its own thread, named after the key
    q1.undeclare()
    q2.undeclare()


def test_an_unknown_code_still_reaches_the_client_as_a_service_error(sessions) -> None:
    server, client = sessions

    class RobotTrouble(Exception):
        code, message, details = "PORT_ERROR", "the port went away", {"port": "/dev/x"}
    q = server.declare_queryable("r/x", guarded("r/x", lambda q: (_ for _ in ()).throw(
        RobotTrouble()), exact=True, coded=(RobotTrouble,)), complete=True)
    with pytest.raises(ServiceError) as e:
        _decoded(client, "r/x")
    assert e.value.code == "PORT_ERROR" and e.value.details == {"port": "/dev/x"}
    q.undeclare()


def _sources(package: str) -> dict[str, str]:
    return {str(p.relative_to(SRC / package)): p.read_text("utf-8")
            for p in sorted((SRC / package).rglob("*.py"))}


def test_one_guard_one_replier_one_json_constant() -> None:
    every = {f"{pkg}/{k}": v for pkg in ("service", "client", "execution", "contract")
             for k, v in _sources(pkg).items()}
    assert len(every) > 40
    guard_users = sorted(p for p, s in every.items() if "addressed_exactly(" in s)
    assert guard_users == ["service/keyguard.py", "service/queries.py"]
    # the error body is built once (wire.error_json); error replies go through
    # queries.reply_error, but for relaying another key's error payload as it came
    built = sorted(p for p, s in every.items() if re.search(r'\{"error": \{"code": ', s))
    assert built == ["contract/wire.py"]
    own_err = sorted(p for p, s in every.items()
                     if re.search(r"reply_err\(wire\.encode", s))
    assert own_err == ["service/queries.py"]
    consts = sorted(p for p, s in every.items() if re.search(r'^JSON = "application/json"', s, re.M))
    assert consts == ["contract/wire.py"]
    assert not [p for p, s in _sources("service").items() if "hasattr(ext" in s]
