"""Carried objects in the kept scene through a real `arduinobot serve`: attach, plan around
a table with the carried box (an independent FCL check of the box at its link's pose every
0.002 rad of the returned trajectory), fk reports the box, detach leaves it where it was
carried to, every refusal coded with the scene unchanged, kill -9 then a restart keeps the
attachment; the `arduinobot scene attach/detach` command as typed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from tests.helpers.carry import shipped_case
from tests.helpers.cli import run_cli
from tests.helpers.fk import link_pose
from tests.helpers.serve import start_servers
from tests.planner.planning.test_carried import _box_hits
from tests.service.test_scene_carry import _pose
from tests.service.test_scene_service import _kill_tree

pytestmark = pytest.mark.slow  # every test here starts serve processes

START = {"joint_1": -0.8}
END = {"joint_1": 0.8}
case = pytest.fixture(shipped_case, scope="module", name="case")


def _box_in_world(case, state) -> dict:
    """The case's box (in its link's frame) as a free object where the link holds it at
    ``state``."""
    from arduinobot.description.model import rpy_of
    t = link_pose(case.d.robot, case.link, case.names, case.q(state)) @ case.box.pose()
    return {"id": case.box.id, "shape": "box", "size": list(case.box.size),
            "xyz": t[:3, 3].tolist(), "rpy": rpy_of(t[:3, :3])}


def _table(case) -> dict:
    t = case.table
    return {"id": t.id, "shape": "box", "size": list(t.size), "xyz": list(t.xyz)}


def test_attach_plan_fk_detach_refusals_and_kill_9(case, tmp_path):
    scene_file = str(tmp_path / "scene.json")
    srv = start_servers([["--workers", "1", "--scene-file", scene_file]])[0]
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            c.request("scene/apply", {"add": [_table(case), _box_in_world(case, START)]})
            got = c.request("scene/apply", {"attach": [{"object": "carried_box",
                                                        "link": case.link, "mass": 0.2}],
                                            "state": START})
            assert got["state_source"] == "request" and got["attached"] == 1
            rev = got["revision"]
            scene = c.request("scene")
            assert [o["id"] for o in scene["objects"]] == ["table"]
            (held,) = scene["attached"]
            assert np.allclose(_pose(held["object"]), case.box.pose(), atol=1e-9)

            # the plan carries the box around the table: no contact by FCL at 0.002 rad
            plan = c.plan({"start": START, "goal": {"joints": END}, "seed": 3,
                           "planning_time": 5.0})
            assert plan.raw["scene_revision"] == rev
            qs = np.array([p["positions"] for p in plan.raw["trajectory"]["points"]])
            assert np.allclose(qs[-1][0], 0.8, atol=1e-3)
            assert _box_hits(case.d, case.names, qs, case.box, case.link, case.table) == 0
            # fk and check report where the box is
            fk = c.request("fk", {"joints": END})
            want = link_pose(case.d.robot, case.link, case.names, case.q(END)) \
                @ case.box.pose()
            assert np.allclose(np.array(fk["carried"]["carried_box"]["matrix"]), want,
                               atol=1e-9)
            chk = c.request("check", {"joints": {}})  # at 0 the box is in the table
            assert not chk["valid"] and "carried_box" in chk["carried"]
            assert {frozenset(p) for p in chk["pairs"]} >= {frozenset(("carried_box",
                                                                       "table"))}

            # every refusal coded, naming the field, the scene unchanged
            before = c.request("scene")
            ball_at = link_pose(case.d.robot, "horizontal_arm", case.names,
                                 case.q({}))[:3, 3].tolist()
            for change, field in [
                ({"attach": [{"object": "table", "link": "no_link"}]}, "attach[0].link"),
                ({"attach": [{"object": "ghost", "link": case.link}]}, "attach[0].object"),
                ({"detach": ["table"]}, "detach[0]"),
                ({"remove": ["carried_box"]}, "remove[0]"),
                ({"attach": [{"object": {"id": "ball", "shape": "sphere", "radius": 0.05,
                                         "xyz": ball_at}, "link": case.link}],
                  "state": {}}, "attach[0]"),
                ({"add": [{"id": "x", "shape": "sphere", "radius": 0.1}],
                  "detach": ["x"]}, "detach[0]"),
            ]:
                with pytest.raises(errors.InvalidRequest) as e:
                    c.request("scene/apply", change)
                assert e.value.details["field"] == field, (change, e.value)
                if field == "attach[0]":
                    assert ["ball", "horizontal_arm"] in e.value.details["pairs"]
                assert c.request("scene") == before

            # kill -9 right after an acknowledged change: a restart has the attachment
            detached = c.request("scene/apply", {"detach": ["carried_box"], "state": END,
                                                 "if_revision": rev})
            assert detached["revision"] == rev + 1 and detached["attached"] == 0
            again = c.request("scene/apply", {"attach": [{"object": "carried_box",
                                                          "link": case.link, "mass": 0.2}]})
            # no state given: the service's executing robot (its twin, at rest at 0)
            assert again["state_source"] == "robot"
        _kill_tree(srv)
        srv = start_servers([["--workers", "1", "--scene-file", scene_file]])[0]
        with PlannerClient(srv.endpoint, timeout=120) as c:
            scene = c.request("scene")
            assert scene["revision"] == rev + 2
            (held,) = scene["attached"]
            assert held["link"] == case.link and held["mass"] == 0.2
            # detached at END, taken again at 0: the box is now where END put it, seen
            # from the link at 0
            at_end = link_pose(case.d.robot, case.link, case.names, case.q(END)) \
                @ case.box.pose()
            link0 = link_pose(case.d.robot, case.link, case.names, case.q({}))
            assert np.allclose(link0 @ _pose(held["object"]), at_end, atol=1e-9)
            chk = c.request("check", {"joints": {}})
            assert chk["scene_revision"] == rev + 2
            assert np.allclose(np.array(chk["carried"]["carried_box"]["matrix"]), at_end,
                               atol=1e-9)
    finally:
        if srv.proc.poll() is None:
            srv.stop()


def test_detach_leaves_the_box_where_it_was_carried_to(case, tmp_path):
    srv = start_servers([["--workers", "1", "--no-robot", "--scene-file",
                          str(tmp_path / "s.json")]])[0]
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            c.request("scene/apply", {"add": [_box_in_world(case, {})]})
            r = c.request("scene/apply", {"attach": [{"object": "carried_box",
                                                      "link": case.link}]})
            assert r["state_source"] == "zero"  # no --state, no executing robot
            r = c.request("scene/apply", {"detach": ["carried_box"], "state": END})
            (free,) = c.request("scene")["objects"]
            want = link_pose(case.d.robot, case.link, case.names, case.q(END)) \
                @ case.box.pose()
            assert np.allclose(_pose(free), want, atol=1e-9)
    finally:
        srv.stop()


def test_the_scene_attach_and_detach_commands_as_typed(case, tmp_path):
    srv = start_servers([["--workers", "1", "--scene-file", str(tmp_path / "s.json")]])[0]
    con = ["--connect", srv.endpoint]
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            c.request("scene/apply", {"add": [_box_in_world(case, START)]})
        out = run_cli("scene", "attach", "carried_box", "--link", case.link, "--mass", "0.2",
                   "--com", "0,0,0.01", "--touch", f"{case.link},gripper_left,gripper_right",
                   "--state", "-0.8", *con)
        assert out.returncode == 0, out.stderr
        assert "revision 2 (0 objects, 1 carried), at --state" in out.stdout
        out = run_cli("scene", "show", *con)
        assert "1 carried" in out.stdout and f"in {case.link}'s frame" in out.stdout
        # fk prints where the carried box is at the asked state, by the independent walk
        out = run_cli("fk", "--joints", "joint_1=0.3,joint_2=0.2", "--link", case.link, *con)
        assert out.returncode == 0, out.stderr
        (line,) = [ln for ln in out.stdout.splitlines() if ln.startswith("carried_box ")]
        assert line.endswith(f"carried by {case.link}"), line
        xyz = [float(v) for v in line.split("xyz (", 1)[1].split(")", 1)[0].split()]
        want = link_pose(case.d.robot, case.link, case.names,
                         case.q({"joint_1": 0.3, "joint_2": 0.2})) @ case.box.pose()
        assert xyz == pytest.approx(want[:3, 3].tolist(), abs=1e-4)  # printed to 0.1 mm
        saved = tmp_path / "cell.json"
        assert run_cli("scene", "save", str(saved), *con).returncode == 0
        body = json.loads(saved.read_text())
        assert body["attached"][0]["com"] == [0, 0, 0.01]
        out = run_cli("scene", "attach", "nothing", "--link", case.link, *con)
        assert out.returncode == 1 and "attach[0].object" in out.stderr
        out = run_cli("scene", "detach", "carried_box", "--state", "joint_1=0.8", *con)
        assert out.returncode == 0 and "revision 3 (1 objects)" in out.stdout, out.stderr
        out = run_cli("scene", "detach", "carried_box", *con)
        assert out.returncode == 1 and "detach[0]" in out.stderr
        # a saved scene with a carried object loads back carried
        out = run_cli("scene", "load", str(saved), *con)
        assert out.returncode == 0 and "1 carried" in out.stdout, out.stderr
        with PlannerClient(srv.endpoint, timeout=120) as c:
            assert c.request("scene")["attached"] == body["attached"]
    finally:
        srv.stop()
