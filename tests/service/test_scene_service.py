"""The kept scene through real `arduinobot serve` instances, as a user types it: two
instances share every change, a late one catches up, kill -9 loses no acknowledged
change, concurrent writers with if_revision lose nothing, every bad input is coded and
changes nothing; the `arduinobot scene` command and `plan --local --scene`."""

from __future__ import annotations

import base64
import json
import os
import signal
import threading
import time

import pytest
import trimesh
import zenoh

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.contract.zconfig import zenoh_config
from tests.helpers.cli import run_cli
from tests.helpers.procs import process_tree
from tests.helpers.serve import free_port, start_servers
from tests.service.test_service_security import secured  # noqa: F401 -- a fixture used below

pytestmark = pytest.mark.slow  # every test here starts serve processes

TABLE = {"id": "table", "shape": "box", "size": [1, 1, 0.1], "xyz": [0, 1, 0.5]}
GOAL = {"goal": {"named": "reach_left"}, "seed": 3}


def _mesh(oid: str, extents: float = 0.1, **extra) -> dict:
    stl = trimesh.creation.box(extents=(extents,) * 3).export(file_type="stl")
    return {"id": oid, "shape": "mesh", "xyz": [1.5, 1.5, 1.5],
            "mesh": {"format": "stl", "data": base64.b64encode(stl).decode()}, **extra}


def _kill_tree(srv) -> None:
    """kill -9 the instance and everything it started (as a crash of the host would)."""
    procs = process_tree(srv.proc.pid)
    for pid in procs:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    srv.proc.wait(10)


def _wait_instances(c: PlannerClient, n: int, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while len(c.instances(refresh=True)) < n:
        assert time.monotonic() < deadline, "instances did not come up"
        time.sleep(0.1)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A router and two instances, each with its own scene file."""
    d = tmp_path_factory.mktemp("scenes")
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router = zenoh.open(zenoh_config(mode="router", listen=[endpoint]))
    files = [str(d / "a" / "scene.json"), str(d / "b" / "scene.json")]
    servers = []
    try:
        servers = start_servers([["--workers", "1", "--connect", endpoint,
                                  "--scene-file", f] for f in files])
        yield endpoint, servers, files, d
    finally:
        for s in servers:
            s.stop()
        router.close()


def test_two_instances_plan_against_the_same_revision(cluster):
    endpoint, (a, b), _, _ = cluster
    with PlannerClient(endpoint, timeout=60) as c:
        _wait_instances(c, 2)
        start = c.request("scene")["revision"]
        # through a: both see it; through b (not necessarily the leader): both see it
        r1 = c.request("scene/apply", {"add": [TABLE]}, instance=a.instance)
        assert r1["revision"] == start + 1
        pb = c.plan({**GOAL, "scene_revision": r1["revision"]}, instance=b.instance)
        pa = c.plan(GOAL, instance=a.instance)
        assert pa.raw["scene_revision"] == pb.raw["scene_revision"] == r1["revision"]
        r2 = c.request("scene/apply", {"add": [_mesh("bin")]}, instance=b.instance)
        assert r2["revision"] == r1["revision"] + 1
        for inst in (a.instance, b.instance):
            scene = c.request("scene", instance=inst)
            assert scene["revision"] == r2["revision"]
            assert [o["id"] for o in scene["objects"]][-2:] == ["table", "bin"]
            chk = c.request("check", {"joints": {}}, instance=inst)
            assert chk["scene_revision"] == r2["revision"]
        # the table is in both instances' worlds: a state through it collides in each
        for inst in (a.instance, b.instance):
            with pytest.raises(errors.InvalidRequest) as e:  # a request may not shadow it
                c.request("check", {"obstacles": [TABLE]}, instance=inst)
            assert e.value.details["field"] == "obstacles[0].id"
        # a plan pinned to an old revision is refused, naming the current one
        with pytest.raises(errors.SceneConflict) as e:
            c.plan({**GOAL, "scene_revision": r1["revision"]}, instance=a.instance)
        assert e.value.details["current_revision"] == r2["revision"]


def test_the_table_is_avoided_by_every_instance(cluster):
    endpoint, (a, b), _, _ = cluster
    wall = {"id": "wall", "shape": "box", "size": [0.05, 2, 2], "xyz": [0, 0.25, 0.5]}
    with PlannerClient(endpoint, timeout=60) as c:
        c.request("scene/apply", {"add": [wall]})
        for inst in (a.instance, b.instance):
            chk = c.request("check", {"joints": {}}, instance=inst)
            assert not chk["valid"] and ["base_link", "wall"] in chk["pairs"]
            with pytest.raises(errors.StartInCollision):
                c.plan(GOAL, instance=inst)
        c.request("scene/apply", {"remove": ["wall"]})
        assert c.request("check", {"joints": {}}, instance=b.instance)["valid"]


BAD = [
    ({"add": [TABLE | {"id": "dup"}, TABLE | {"id": "dup"}]}, "add[1].id", "INVALID_REQUEST"),
    ({"remove": ["nothere"]}, "remove[0]", "INVALID_REQUEST"),
    ({"if_revision": 0, "clear": True}, "if_revision", "SCENE_CONFLICT"),
    ({"add": [TABLE | {"id": "x", "frame": "claw"}]}, "add[0].frame", "INVALID_REQUEST"),
    ({"add": [TABLE | {"id": "x", "frame": "claw_support", "touch_links": ["finger"]}]},
     "add[0].touch_links[0]", "INVALID_REQUEST"),
    ({"attach": [{"object": "table", "link": "no_link"}]}, "attach[0].link", "INVALID_REQUEST"),
    ({"add": [_mesh("m") | {"mesh": {"format": "stl", "data": "@@"}}]}, "add[0].mesh.data",
     "INVALID_REQUEST"),
    ({"add": [_mesh("m", extents=1.0, scale=101)]}, "add[0].mesh", "INVALID_REQUEST"),
    ({"add": [_mesh("m") | {"mesh": {"format": "obj", "data": base64.b64encode(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").decode()}}]}, "add[0].mesh",
     "INVALID_REQUEST"),
    ({"add": [{"id": "s", "shape": "sphere", "radius": 0.01, "xyz": [0, 0, 1e9]}]},
     "add[0].xyz[2]", "INVALID_REQUEST"),
    ({"add": [{"id": f"s{i}", "shape": "sphere", "radius": 0.01} for i in range(256)]},
     "add", "INVALID_REQUEST"),
]


def test_an_apply_sent_twice_is_applied_once(cluster):
    """A retry of an apply (the same apply_id) through either instance is answered with
    the revision the first made, already_applied, and the scene stays as it was; the
    client's apply() gives each call its own id."""
    endpoint, (a, b), _, _ = cluster
    with PlannerClient(endpoint, timeout=60) as c:
        _wait_instances(c, 2)
        change = {"add": [TABLE | {"id": "once"}], "apply_id": "add-once-1"}
        first = c.request("scene/apply", change, instance=a.instance)
        assert "already_applied" not in first
        for inst in (b.instance, a.instance):
            again = c.request("scene/apply", change, instance=inst)
            assert again == {**first, "already_applied": True}, inst
            assert c.request("scene", instance=inst)["revision"] == first["revision"]
        removed = c.apply(remove=["once"])
        assert not removed.already_applied and removed.revision == first["revision"] + 1
        with pytest.raises(errors.InvalidRequest) as e:  # a new id: a new change
            c.apply(remove=["once"])
        assert e.value.details["field"] == "remove[0]"
        with pytest.raises(errors.InvalidRequest) as e:
            c.request("scene/apply", {"clear": True, "apply_id": "not/an id"})
        assert e.value.details["field"] == "apply_id"


def test_a_token_that_is_no_instance_leads_nothing(cluster):
    """Issue 39: the smallest id among `alive/*` tokens led, so a token of a session that
    is no serve (declared here from a session of its own, behind the router without an
    ACL, as a service's credentials allow) made every apply wait 10 s, then BUSY. Now
    an apply through either instance is acknowledged by the smallest id that answers and
    both instances hold it."""
    endpoint, (a, b), _, _ = cluster
    fake = zenoh.open(zenoh_config(mode="client", connect=[endpoint]))
    token = fake.liveliness().declare_token("arduinobot/alive/0")
    try:
        with PlannerClient(endpoint, timeout=60) as c:
            _wait_instances(c, 3)  # the fake among them, as the instances see it
            replies = [c.request("scene/apply", {"add": [TABLE | {"id": f"t{inst[:6]}"}]},
                                 instance=inst) for inst in (a.instance, b.instance)]
            lead = min(a.instance, b.instance)
            assert [r.get("leader") for r in replies] == [lead, lead], replies
            assert replies[1]["revision"] == replies[0]["revision"] + 1
            assert not any("not_taken_by" in r for r in replies), replies
            scenes = [c.request("scene", instance=i) for i in (a.instance, b.instance)]
            assert scenes[0] == scenes[1]
            ids = {o["id"] for o in scenes[0]["objects"]}
            assert {f"t{a.instance[:6]}", f"t{b.instance[:6]}"} <= ids
            for inst in (a.instance, b.instance):
                c.apply(remove=[f"t{inst[:6]}"])
    finally:
        token.undeclare()
        fake.close()


def test_a_follower_paused_past_its_lease_catches_up_and_never_plans_on_the_old_scene(cluster):
    """Issue 39, item 1: the follower stopped (SIGSTOP, as a VM pause) until the leader
    no longer counts it; an apply is acknowledged without it. Back, it answered against
    the old revision for good; now each of its answers is BUSY (catching up), no reply
    (its session not back yet) or the new revision, and it gets there."""
    endpoint, (a, b), _, _ = cluster
    leader, follower = sorted((a, b), key=lambda s: s.instance)
    with PlannerClient(endpoint, timeout=60) as c:
        _wait_instances(c, 2)
        before = c.request("scene")["revision"]
        assert c.request("check", {"joints": {}},
                         instance=follower.instance)["scene_revision"] == before
        procs = process_tree(follower.proc.pid)
        for pid in procs:
            os.kill(pid, signal.SIGSTOP)
        try:
            for _ in range(600):  # until its lease ran out (a bound, not a timing)
                if follower.instance not in c.instances(refresh=True):
                    break
                time.sleep(0.1)
            assert follower.instance not in c.instances(refresh=True)
            applied = c.apply(add=[TABLE | {"id": "while_away"}])
            assert applied.revision == before + 1
        finally:
            for pid in procs:
                os.kill(pid, signal.SIGCONT)
        seen: list[object] = []
        for _ in range(1200):
            try:
                rev = c.request("check", {"joints": {}},
                                instance=follower.instance)["scene_revision"]
                seen.append(rev)
                if rev == applied.revision:
                    break
            except errors.ServiceBusy as e:
                assert e.details.get("reason") == "catching_up", e
                seen.append("busy")
            except (errors.ServiceUnavailable, errors.RequestTimeout):
                seen.append("away")
            time.sleep(0.05)
        print(f"\nthe follower's answers after its return: {seen[:3]} ... {seen[-3:]}")
        assert seen[-1] == applied.revision, seen
        assert before not in seen, seen  # never against the old scene
        scene = c.request("scene", instance=follower.instance)
        assert "while_away" in [o["id"] for o in scene["objects"]]
        c.apply(remove=["while_away"])


def test_every_bad_apply_is_coded_names_the_field_and_changes_nothing(cluster):
    endpoint, (a, b), _, _ = cluster
    with PlannerClient(endpoint, timeout=60) as c:
        c.request("scene/apply", {"add": [TABLE | {"id": "keep"}]})
        before = [c.request("scene", instance=i) for i in (a.instance, b.instance)]
        for change, field, code in BAD:
            for inst in (a.instance, b.instance):
                with pytest.raises(errors.ServiceError) as e:
                    c.request("scene/apply", change, instance=inst)
                    pytest.fail(f"accepted {str(change)[:200]}")
                assert (e.value.code, e.value.details.get("field")) == (code, field), change
        with pytest.raises(errors.InvalidRequest):
            c.request("scene/apply", b"{not json")
        # a wildcard reaches no key that changes the scene (arduinobot.service.keyguard): not even
        # an error comes back from one
        clear = json.dumps({"clear": True}).encode()
        for key in ("arduinobot/**", "arduinobot/scene/*", "arduinobot/scene/app$*",
                    f"arduinobot/instance/{a.instance}/scene/*",
                    "arduinobot/instance/*/scene/lead", "arduinobot/instance/*/scene/sync"):
            got = [(str(r.ok.key_expr) if r.ok else "err") for r in
                   c.session.get(key, payload=clear, timeout=5)]
            assert not [k for k in got if k == "err" or k.endswith(("/apply", "/lead",
                                                                     "/sync"))], (key, got)
        after = [c.request("scene", instance=i) for i in (a.instance, b.instance)]
        assert after == before


def test_concurrent_writers_with_if_revision_lose_nothing(cluster):
    """Four writers (two through each instance), each replacing its own object
    ``w<k>-<i>`` with if_revision: every acknowledged apply counts one revision, the scene
    ends with every writer's last acknowledged object, every refusal is SCENE_CONFLICT.
    (bench/scene_writers.py runs 4 x 250.)"""
    endpoint, (a, b), _, _ = cluster
    n = 25
    acked: dict[int, list[str]] = {k: [] for k in range(4)}
    conflicts = [0] * 4
    other: list[BaseException] = []
    with PlannerClient(endpoint, timeout=60) as setup:
        setup.request("scene/apply", {"clear": True})
        start = setup.request("scene")["revision"]

    def writer(k: int) -> None:
        inst = (a, b)[k % 2].instance
        with PlannerClient(endpoint, timeout=60) as c:
            i = 0
            while len(acked[k]) < n:
                rev = c.request("scene", instance=inst)["revision"]
                oid = f"w{k}-{i}"
                change = {"add": [{"id": oid, "shape": "sphere", "radius": 0.01,
                                   "xyz": [2, k, 2]}], "if_revision": rev}
                if acked[k]:
                    change["remove"] = [acked[k][-1]]
                i += 1
                try:
                    c.request("scene/apply", change, instance=inst)
                except errors.SceneConflict as e:
                    assert e.details["current_revision"] > rev
                    conflicts[k] += 1
                    continue
                except BaseException as e:  # noqa: BLE001 -- reported below
                    other.append(e)
                    return
                acked[k].append(oid)

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(600)
    assert not other, other
    with PlannerClient(endpoint, timeout=60) as c:
        for inst in (a.instance, b.instance):
            scene = c.request("scene", instance=inst)
            assert scene["revision"] == start + 4 * n
            assert sorted(o["id"] for o in scene["objects"]) == \
                sorted(acked[k][-1] for k in range(4))
    assert sum(conflicts) > 0  # they did race


def test_a_late_instance_catches_up_the_leader_fails_over_and_kill_9_loses_nothing(cluster):
    endpoint, (a, b), files, d = cluster
    late_file = str(d / "late" / "scene.json")
    with PlannerClient(endpoint, timeout=60) as c:
        rev = c.request("scene/apply", {"clear": True, "add": [TABLE, _mesh("bin")]}
                        )["revision"]
        late = start_servers([["--workers", "1", "--connect", endpoint, "--scene-file",
                               late_file]])[0]
        by_file = {a.instance: files[0], b.instance: files[1], late.instance: late_file}
        servers = {s.instance: s for s in (a, b, late)}
        try:
            # ready means caught up: its first plan already uses the scene
            assert c.plan(GOAL, instance=late.instance).raw["scene_revision"] == rev
            assert c.request("scene", instance=late.instance)["objects"][0]["id"] == "table"
            retry = {"remove": ["table"], "apply_id": "remove-table-7f3a"}
            rev = c.request("scene/apply", retry)["revision"]
            # kill -9 the leader (the smallest id); the next one leads
            leader = min(servers)
            _kill_tree(servers.pop(leader))
            left = sorted(servers)
            # the same apply again (as an instance re-sends one whose leader died having
            # applied it): the new leader took it, says so, and changes nothing (it
            # answered "remove[0]: no object 'table'" for a change that was made)
            again = c.request("scene/apply", retry, instance=left[-1])
            assert again["already_applied"] is True and again["revision"] == rev
            assert c.request("scene", instance=left[0])["revision"] == rev
            after = c.request("scene/apply", {"add": [TABLE | {"id": "after"}],
                                              "if_revision": rev}, instance=left[-1])
            assert after["revision"] == rev + 1
            for inst in left:
                assert c.plan(GOAL, instance=inst).raw["scene_revision"] == rev + 1
        finally:
            for srv in servers.values():  # right after an acknowledged apply
                _kill_tree(srv)
    # each restarted alone (no other instance to catch up from): its own file has every
    # change it acknowledged or took
    for inst, f in by_file.items():
        srv = start_servers([["--workers", "1", "--scene-file", f]])[0]
        try:
            with PlannerClient(srv.endpoint, timeout=60) as c:
                scene = c.request("scene")
            want = (rev, ["bin"]) if inst == leader else (rev + 1, ["bin", "after"])
            assert (scene["revision"], [o["id"] for o in scene["objects"]]) == want, f
        finally:
            srv.stop()


def test_the_scene_command_as_a_user_types_it(tmp_path):
    srv = start_servers([["--workers", "1", "--scene-file", str(tmp_path / "s.json")]])[0]
    con = ["--connect", srv.endpoint]
    mesh = tmp_path / "bin.stl"
    mesh.write_bytes(trimesh.creation.box(extents=(100, 100, 100)).export(file_type="stl"))
    try:
        out = run_cli("scene", "add", "box:table:1,1,0.1@0,1,0.5", "sphere:ball:0.05@1,1,1",
                   *con)
        assert out.returncode == 0 and "revision 1 (2 objects)" in out.stdout, out.stderr
        out = run_cli("scene", "add-mesh", "bin", str(mesh), "--pose", "1.5,1.5,1.5",
                   "--scale", "0.001", "--if-revision", "1", *con)
        assert out.returncode == 0 and "revision 2" in out.stdout, out.stderr
        out = run_cli("scene", "remove", "ball", "--if-revision", "1", *con)
        assert out.returncode == 1 and "SCENE_CONFLICT" in out.stderr
        assert '"current_revision": 2' in out.stderr
        out = run_cli("scene", "show", *con)
        assert "revision 2: 3 object(s)" in out.stdout and "stl mesh" in out.stdout
        saved = tmp_path / "cell.json"
        out = run_cli("scene", "save", str(saved), *con)
        assert out.returncode == 0 and json.loads(saved.read_text())["revision"] == 2
        # plan and check-state use the service's scene
        out = run_cli("check-state", "--joints", "0,0,0", "--json", *con)
        assert json.loads(out.stdout)["scene_revision"] == 2
        assert run_cli("scene", "clear", *con).returncode == 0
        out = run_cli("scene", "load", str(saved), *con)
        assert out.returncode == 0 and "revision 4 (3 objects)" in out.stdout, out.stderr
        out = run_cli("scene", "add-mesh", "x", str(tmp_path / "none.stl"), *con)
        assert out.returncode == 2 and "cannot read" in out.stderr
        # an object fixed in a link's frame moves with the link: 0.3 m above the claw
        # support it meets an orb at joint_1 = 0, not at joint_1 = 1
        out = run_cli("scene", "add", "sphere:orb:0.03@-0.02,1.02,1.757", *con)
        assert out.returncode == 0, out.stderr
        out = run_cli("scene", "add", "box:cam:0.05,0.05,0.05@0,0.2,0.3", "--frame",
                   "claw_support", *con)
        assert out.returncode == 0 and "revision 6" in out.stdout, out.stderr
        assert "cam" in run_cli("scene", "show", *con).stdout.split("claw_support's frame")[0]
        out = run_cli("check-state", "--joints", "0,0,0", "--json", *con)
        assert sorted(json.loads(out.stdout)["pairs"]) == [["cam", "orb"]], out.stdout
        out = run_cli("check-state", "--joints", "1,0,0", "--json", *con)
        assert json.loads(out.stdout)["valid"], out.stdout
        out = run_cli("fk", "--joints", "1,0,0", "--link", "claw_support", *con)
        (line,) = [ln for ln in out.stdout.splitlines() if ln.startswith("cam ")]
        assert line.endswith("fixed to claw_support"), line  # not "carried by": not picked up
        out = run_cli("scene", "add", "box:x:1,1,1@5,5,5", "--touch-links", "base_link", *con)
        assert out.returncode == 2 and "--touch-links needs --frame" in out.stderr
    finally:
        srv.stop()
    # --local reads a saved scene: a wall there makes the zero state collide
    wall = {"revision": 7, "objects": [{"id": "wall", "shape": "box", "size": [0.05, 2, 2],
                                        "xyz": [0, 0.25, 0.5]}], "attached": []}
    (tmp_path / "wall.json").write_text(json.dumps(wall))
    out = run_cli("check-state", "--local", "--scene", str(tmp_path / "wall.json"), "--joints",
               "0,0,0", "--json")
    assert out.returncode == 1
    body = json.loads(out.stdout)
    assert body["scene_revision"] == 7 and ["base_link", "wall"] in body["pairs"]
    out = run_cli("check-state", "--scene", str(tmp_path / "wall.json"))
    assert out.returncode == 2 and "--scene is for --local" in out.stderr


def test_through_the_shipped_acl_viewers_read_the_scene_planners_change_it(secured):  # noqa: F811
    """The shipped router template: a viewer reads the scene (and may not change it), a
    planner changes it; no user reaches the keys between instances."""
    from tests.service.test_service_security import _replies, _session, client_config
    tmp, pki, endpoint, _, srv = secured
    viewer = _session(client_config(tmp, pki, "viewer"), endpoint)
    planner = _session(client_config(tmp, pki, "planner"), endpoint)
    add = json.dumps({"add": [TABLE | {"id": "acl"}]}).encode()
    try:
        assert _replies(viewer, "arduinobot/scene", b"") == ["ok arduinobot/scene"]
        own = f"arduinobot/instance/{srv.instance}/scene"
        assert _replies(viewer, own, b"") == [f"ok {own}"]
        assert _replies(viewer, "arduinobot/scene/apply", add) == []
        assert _replies(planner, "arduinobot/scene/apply", add) == \
            ["ok arduinobot/scene/apply"]
        sync = json.dumps({"from": "x", "base": 0, "revision": 1, "change": {}}).encode()
        for user in (viewer, planner):
            for key in (f"arduinobot/instance/{srv.instance}/scene/lead",
                        f"arduinobot/instance/{srv.instance}/scene/sync",
                        f"arduinobot/instance/{srv.instance}/scene/ready"):
                assert _replies(user, key, sync) == [], key
        reply = next(iter(viewer.get("arduinobot/scene", timeout=5)))
        assert [o["id"] for o in json.loads(reply.ok.payload.to_bytes())["objects"]] == ["acl"]
    finally:
        _replies(planner, "arduinobot/scene/apply", json.dumps({"clear": True}).encode())
        viewer.close()
        planner.close()
