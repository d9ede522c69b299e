"""The service exposed through a real router (``python -m arduinobot.service.router``) configured by
the shipped templates (src/arduinobot/service/security/*.json5): TLS with a test CA generated here,
user/password, and the default-deny access-control list, end to end with a real
`arduinobot serve` behind the router."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import zenoh

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from tests.helpers.serve import free_port
from tests.helpers.zrouter import (
    SECURITY,
    derive_config,
    launch_serves,
    make_test_pki,
    start_router,
)

PASSWORDS = {"service": "svc-6f1c", "planner": "plan-93ad", "viewer": "view-4b7e",
             "operator": "op-d20a"}
PLAN = {"goal": {"named": "reach_left"}, "seed": 3}
WORK_AND_ROBOT = ("plan", "fk", "ik", "check", "execute", "cancel", "robot_state")
#: [s] bounds a failure only, it synchronises nothing: a query ends when every queryable
#: it reached (or the router, for a denied one) has said it is done, with or without a
#: reply; one that ran into this bound instead shows as an ``err b'Timeout'`` reply, which
#: no assertion here accepts
REPLY_WAIT = 30.0
pytestmark = pytest.mark.slow


def _router_config(tmp: Path, pki, endpoint: str, **extra: object) -> dict[str, object]:
    users = tmp / "users.txt"
    users.write_text("".join(f"{u}:{p}\n" for u, p in PASSWORDS.items()))
    users.chmod(0o600)
    return {"listen/endpoints": [endpoint],
            "transport/link/tls/listen_certificate": str(pki.cert),
            "transport/link/tls/listen_private_key": str(pki.key),
            "transport/auth/usrpwd/dictionary_file": str(users), **extra}


@pytest.fixture(scope="module")
def secured(tmp_path_factory):
    """The shipped router template on a loopback TLS port, and one service behind it
    with the shipped service template (no listener of its own)."""
    tmp = tmp_path_factory.mktemp("secured")
    pki = make_test_pki(tmp / "pki")
    endpoint = f"tls/127.0.0.1:{free_port()}"
    # the admin space on, as an operator might switch it on: the ACL must still hide it
    cfg = derive_config(SECURITY / "router.json5", tmp / "router.json5",
                        _router_config(tmp, pki, endpoint, **{"adminspace/enabled": True}))
    router = start_router(endpoint, config=cfg)
    svc_cfg = derive_config(SECURITY / "service.json5", tmp / "service.json5", {
        "connect/endpoints": [endpoint],
        "transport/link/tls/root_ca_certificate": str(pki.ca),
        "transport/auth/usrpwd/password": PASSWORDS["service"]})
    servers = []
    try:
        servers = launch_serves([["--config", str(svc_cfg), "--workers", "1"]])
        yield tmp, pki, endpoint, router, servers[0]
    finally:
        for s in servers:
            s.stop()
        router.stop()


def client_config(tmp: Path, pki, user: str | None, password: str | None = None, *,
                  ca: Path | None | bool = True) -> Path:
    """The shipped client template for ``user`` (None: no credentials) trusting ``ca``
    (True: the test CA; None: no CA given)."""
    settings: dict[str, object] = {
        "transport/link/tls/root_ca_certificate": str(pki.ca) if ca is True else
        (str(ca) if ca else None),
        "transport/auth/usrpwd/user": user,
        "transport/auth/usrpwd/password": password if password is not None else
        PASSWORDS.get(user or "")}
    name = f"client-{user}-{password}-{'ca' if ca is True else ca}.json5".replace("/", "_")
    return derive_config(SECURITY / "client.json5", tmp / name, settings)


def _session(cfg: Path, endpoint: str) -> zenoh.Session:
    from arduinobot.contract.zconfig import zenoh_config
    return zenoh.open(zenoh_config(config_file=cfg, connect=[endpoint], listen=[]))


def _replies(session: zenoh.Session, key: str, payload: bytes, *,
             wait: float = REPLY_WAIT) -> list[str]:
    """Every reply to one get, once the query is done: ``ok <key>`` or ``err <payload>``
    (``wait`` [s] only bounds a query that never ends)."""
    out = []
    for r in session.get(key, payload=payload, timeout=wait):
        out.append(f"ok {r.ok.key_expr}" if r.ok is not None
                   else f"err {r.err.payload.to_bytes()[:80]!r}")
    return out


# -- TLS -----------------------------------------------------------------------------
def test_a_client_trusting_the_ca_plans_through_the_router(secured):
    tmp, pki, endpoint, _, srv = secured
    with PlannerClient(endpoint, config_file=client_config(tmp, pki, "planner"),
                       timeout=30) as c:
        res = c.plan(PLAN)
    assert res.duration > 0 and res.request_id.startswith(srv.instance[:8])


@pytest.mark.parametrize("ca", [None, "other"], ids=["no-ca", "wrong-ca"])
def test_a_client_without_the_ca_gets_nothing(secured, ca):
    tmp, pki, endpoint, _, _ = secured
    cfg = client_config(tmp, pki, "planner", ca=pki.other_ca if ca == "other" else None)
    with pytest.raises(errors.ServiceUnavailable) as e:
        PlannerClient(endpoint, config_file=cfg)
    assert e.value.reason == "connect_failed"


def test_plain_tcp_to_the_tls_port_gets_nothing(secured):
    tmp, pki, endpoint, _, _ = secured
    with pytest.raises(errors.ServiceUnavailable) as e:
        PlannerClient(endpoint.replace("tls/", "tcp/"),
                      config_file=client_config(tmp, pki, "planner"))
    assert e.value.reason == "connect_failed"


# -- user/password ---------------------------------------------------------------------
@pytest.mark.parametrize("user,password", [("planner", "wrong"), ("planner", ""),
                                           ("nobody", "plan-93ad"), (None, None)],
                         ids=["wrong-password", "empty-password", "unknown-user",
                              "no-credentials"])
def test_a_wrong_or_missing_password_gets_nothing(secured, user, password):
    tmp, pki, endpoint, _, _ = secured
    with pytest.raises(errors.ServiceUnavailable) as e:
        PlannerClient(endpoint, config_file=client_config(tmp, pki, user, password))
    assert e.value.reason == "connect_failed"


def test_the_right_password_of_another_user_is_refused(secured):
    tmp, pki, endpoint, _, _ = secured
    with pytest.raises(errors.ServiceUnavailable):
        PlannerClient(endpoint, config_file=client_config(tmp, pki, "planner",
                                                          PASSWORDS["viewer"]))


# -- access control ----------------------------------------------------------------------
def test_a_planner_plans_on_shared_and_instance_keys_but_cannot_move_the_arm(secured):
    tmp, pki, endpoint, _, srv = secured
    planner = _session(client_config(tmp, pki, "planner"), endpoint)
    operator = _session(client_config(tmp, pki, "operator"), endpoint)
    try:
        body = json.dumps(PLAN).encode()
        assert _replies(planner, "arduinobot/plan", body) == ["ok arduinobot/plan"]
        own = f"arduinobot/instance/{srv.instance}/plan"
        assert _replies(planner, own, body) == [f"ok {own}"]
        assert _replies(planner, "arduinobot/health", b"") == ["ok arduinobot/health"]
        # moving the arm is the operator's: the planner gets nothing, the operator a reply
        for key in ("arduinobot/robot_state", "arduinobot/execute", "arduinobot/ro$*"):
            assert _replies(planner, key, b"") == [], key
        # the first robot_state builds the twin: seconds with a cold mesh cache
        assert _replies(operator, "arduinobot/robot_state", b"", wait=60.0) == \
            ["ok arduinobot/robot_state"]
    finally:
        planner.close()
        operator.close()


def test_no_user_reaches_the_routers_admin_space(secured):
    """The router's admin space is on in this test (the template has it off); its keys
    answer a session on a router without the ACL, and nobody through the ACL."""
    tmp, pki, endpoint, router, _ = secured
    admin = f"@/{router.zid}/router"
    for user in ("planner", "operator", "service"):
        s = _session(client_config(tmp, pki, user), endpoint)
        try:
            for key in (admin, f"@/{router.zid}/**", "@/**", "**"):
                # (a session's own admin space, @/<its zid>/session/**, is local)
                got = [r for r in _replies(s, key, b"") if r.startswith(f"ok @/{router.zid}")]
                assert got == [], (user, key)
        finally:
            s.close()
    # the same config without the ACL: the admin key is real and answers
    open_ep = f"tls/127.0.0.1:{free_port()}"
    cfg = derive_config(SECURITY / "router.json5", tmp / "router-no-acl.json5",
                        _router_config(tmp, pki, open_ep, **{"adminspace/enabled": True,
                                                             "access_control/enabled": False}))
    bare = start_router(open_ep, config=cfg)
    try:
        s = _session(client_config(tmp, pki, "planner"), open_ep)
        try:
            assert [r for r in _replies(s, f"@/{bare.zid}/router", b"")] == \
                [f"ok @/{bare.zid}/router"]
        finally:
            s.close()
    finally:
        bare.stop()


def test_a_denied_key_answers_through_no_key_expression(secured):
    """The viewer may read health but not plan. Each key expression below matches the
    plan queryables; under a rule that only denied `arduinobot/plan`, every one of them
    returned a plan (issue 13)."""
    tmp, pki, endpoint, _, srv = secured
    viewer = _session(client_config(tmp, pki, "viewer"), endpoint)
    try:
        alive = [str(r.ok.key_expr) for r in
                 viewer.liveliness().get("arduinobot/alive/*", timeout=REPLY_WAIT)
                 if r.ok is not None]
        assert alive == [f"arduinobot/alive/{srv.instance}"]  # ids are public
        assert _replies(viewer, "arduinobot/health", b"") == ["ok arduinobot/health"]
        body = json.dumps(PLAN).encode()
        for key in ("arduinobot/plan", "arduinobot/*", "arduinobot/**", "arduinobot/pl$*",
                    "arduinobot/p$*n", "**", f"arduinobot/instance/{srv.instance}/plan",
                    f"arduinobot/instance/{srv.instance}/*", "arduinobot/instance/*/plan",
                    "arduinobot/instance/**"):
            assert _replies(viewer, key, body) == [], key
    finally:
        viewer.close()


def test_wildcards_reach_no_work_key_even_without_an_acl(server):
    """The service itself answers plan, fk, ik and check only on their exact keys: a
    wildcard would pass an ACL rule written for the key, and fan one query out to every
    work queryable. The same holds for the execute keys. Info keys (health, ...) still
    answer a wildcard."""
    from arduinobot.contract.zconfig import zenoh_config
    s = zenoh.open(zenoh_config(mode="client", connect=[server.endpoint], listen=[]))
    try:
        body = json.dumps({"joints": {}}).encode()
        assert _replies(s, "arduinobot/fk", body) == ["ok arduinobot/fk"]
        before = json.loads(next(iter(s.get("arduinobot/health"))).ok.payload.to_bytes())
        for key in ("arduinobot/*", "arduinobot/**", "arduinobot/f$*", "arduinobot/ex$*",
                    f"arduinobot/instance/{server.instance}/*"):
            got = _replies(s, key, body)
            # no work key, no execute key answers, not even with an error
            assert not [r for r in got if r.split("/")[-1] in WORK_AND_ROBOT
                        or r.startswith("err")], (key, got)
        assert "ok arduinobot/health" in _replies(s, "arduinobot/*", b"")
        after = json.loads(next(iter(s.get("arduinobot/health"))).ok.payload.to_bytes())
        assert after["counters"] == before["counters"]  # no work was even queued
    finally:
        s.close()


# -- the ACL's positive cases: the operator moves the arm; nobody else streams states ------
SLOW_PLAN = {"goal": {"named": "reach_left"}, "velocity_scaling": 0.05,
             "acceleration_scaling": 0.05, "seed": 5}


def test_an_operator_executes_and_another_operator_cancels(secured):
    import threading
    tmp, pki, endpoint, _, _ = secured
    cfg = client_config(tmp, pki, "operator")
    events, outcome = [], {}
    started = threading.Event()

    def on_event(ev):
        events.append(ev)
        if ev.event == "started":
            started.set()

    def run():
        # the first execute builds the twin: seconds with a cold mesh cache
        with PlannerClient(endpoint, config_file=cfg, timeout=120) as op:
            try:
                outcome["done"] = op.execute(plan=SLOW_PLAN, on_event=on_event)
            except Exception as e:  # noqa: BLE001 -- asserted below
                outcome["error"] = e
    t = threading.Thread(target=run)
    t.start()
    try:
        assert started.wait(180), outcome
        with PlannerClient(endpoint, config_file=cfg, timeout=30) as other:
            assert other.cancel_execution(events[0].execution) == events[0].execution
    finally:
        t.join(60)
    assert "error" not in outcome, outcome
    assert outcome["done"].report["outcome"] == "cancelled"
    assert "progress" in [ev.event for ev in events]


def test_a_planner_or_viewer_cannot_publish_joint_states(secured):
    """A subscriber (an operator) sees another operator's joint_states and never a
    planner's or a viewer's. Ordering, not waits: the subscription is known to the router
    once a first operator message came through it; each denied put is followed, on the
    same link, by a query the router answers, so the router had dealt with the put
    before the operator's last marker goes out; the subscriber's link delivers in order."""
    import threading
    tmp, pki, endpoint, _, _ = secured
    cfg = client_config(tmp, pki, "operator")
    watcher, operator = _session(cfg, endpoint), _session(cfg, endpoint)
    others = {u: _session(client_config(tmp, pki, u), endpoint) for u in ("planner", "viewer")}
    seen: list[dict] = []
    got = {"ready": threading.Event(), "last": threading.Event()}

    def on_sample(s):
        msg = json.loads(s.payload.to_bytes())
        seen.append(msg)
        if msg.get("from") == "operator":
            got[msg["marker"]].set()
    sub = watcher.declare_subscriber("arduinobot/joint_states", on_sample)
    try:
        for _ in range(600):  # until the router routes to the new subscription
            operator.put("arduinobot/joint_states",
                         json.dumps({"from": "operator", "marker": "ready"}))
            if got["ready"].wait(0.05):
                break
        assert got["ready"].is_set()
        for user, s in others.items():
            s.put("arduinobot/joint_states", json.dumps({"from": user}))
            assert _replies(s, "arduinobot/health", b"") == ["ok arduinobot/health"]
        operator.put("arduinobot/joint_states", json.dumps({"from": "operator",
                                                           "marker": "last"}))
        assert got["last"].wait(30)
        assert {m["from"] for m in seen if "from" in m} == {"operator"}
    finally:
        sub.undeclare()
        for s in (watcher, operator, *others.values()):
            s.close()


def test_no_client_can_declare_an_instance_or_fake_a_scene_change(secured):
    """Issue 39, item 7: the smallest live id on `arduinobot/alive/*` leads the kept
    scene, and viewers once could declare one (every apply BUSY) and put fake
    `scene/changes`. Ordering, not waits: each client's token and put is followed on the
    same link by a query the router answers, so the router had dealt with them before
    the operator's marker goes out; an allowed token (an executing operator's
    `execute/client/*`) declared the same way is seen, as a control."""
    import threading
    tmp, pki, endpoint, _, srv = secured
    op = client_config(tmp, pki, "operator")
    watcher, operator = _session(op, endpoint), _session(op, endpoint)
    others = {u: _session(client_config(tmp, pki, u), endpoint)
              for u in ("planner", "viewer", "operator")}
    seen: list[dict] = []
    got = threading.Event()

    def on_sample(s):
        seen.append(json.loads(s.payload.to_bytes()))
        got.set()
    sub = watcher.declare_subscriber("arduinobot/scene/changes", on_sample)
    tokens = []
    try:
        for user, s in others.items():
            tokens.append(s.liveliness().declare_token(f"arduinobot/alive/0000{user}"))
            s.put("arduinobot/scene/changes", json.dumps({"from": user}))
            assert _replies(s, "arduinobot/health", b"") == ["ok arduinobot/health"]
        control = operator.liveliness().declare_token("arduinobot/execute/client/c0ntrol")
        assert _replies(operator, "arduinobot/health", b"") == ["ok arduinobot/health"]
        # asked with the service's own rights (it sees every token), declaring none
        observer = _session(client_config(tmp, pki, "service"), endpoint)
        alive = [str(r.ok.key_expr) for r in
                 observer.liveliness().get("arduinobot/alive/*", timeout=REPLY_WAIT)
                 if r.ok is not None]
        assert alive == [f"arduinobot/alive/{srv.instance}"]  # no client's token
        ctl = [str(r.ok.key_expr) for r in
               observer.liveliness().get("arduinobot/execute/client/*", timeout=REPLY_WAIT)
               if r.ok is not None]
        observer.close()
        assert ctl == ["arduinobot/execute/client/c0ntrol"]  # an allowed token is seen
        control.undeclare()
        # a real change comes through to the same subscriber, and nothing before it did
        with PlannerClient(endpoint, config_file=client_config(tmp, pki, "planner"),
                           timeout=30) as c:
            c.request("scene/apply", {"add": [{"id": "acl_box", "shape": "box",
                                               "size": [0.05, 0.05, 0.05],
                                               "xyz": [0.6, 0.6, 0.1]}]})
        assert got.wait(30)
        assert seen and all("from" not in m for m in seen), seen
    finally:
        sub.undeclare()
        for t in tokens:
            t.undeclare()
        for s in (watcher, operator, *others.values()):
            s.close()


def test_only_an_operator_runs_a_task(secured):
    """`arduinobot/task` executes on the arm: the operator's, as execute is (it was in
    no rule: denied to everyone)."""
    tmp, pki, endpoint, _, _ = secured
    body = json.dumps({"number": 99}).encode()  # no such task: an error reply
    for user in ("planner", "viewer"):
        s = _session(client_config(tmp, pki, user), endpoint)
        try:
            assert _replies(s, "arduinobot/task", body) == [], user
        finally:
            s.close()
    s = _session(client_config(tmp, pki, "operator"), endpoint)
    try:
        (reply,) = _replies(s, "arduinobot/task", body)
        assert reply.startswith("err") and b"99" in reply.encode()
    finally:
        s.close()
