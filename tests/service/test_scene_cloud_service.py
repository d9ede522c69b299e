"""A point cloud in the kept scene through a real `arduinobot serve`: the apply's counts,
plans around the pillar it measured (an independent FCL check against a box per pillar
cell, every 0.002 rad) whose replies name the unknown-space assumption, a check that sees
it, a later add of the same id replacing it, hostile clouds coded naming the field with
the scene unchanged and the service serving, and the cloud kept across a restart."""

from __future__ import annotations

import base64

import numpy as np
import pytest

from arduinobot.client import errors
from arduinobot.client.client import PlannerClient
from arduinobot.client.cloud_files import read_cloud_file
from arduinobot.description import load_description
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.scene.cloud import CloudObstacle, encode_points, voxelise
from tests.helpers.cli import run_cli
from tests.helpers.serve import start_servers
from tests.planner.planning.test_carried import _dense
from tests.scene.test_scene_cloud import _hits, _on_the_robot, _table_and_pillar

pytestmark = pytest.mark.slow  # starts serve processes

START = {"joint_1": -0.8}
END = {"joint_1": 0.8}


def test_a_cloud_through_the_service(tmp_path):
    base = MotionPlanner(load_description()).context.world(())
    q0 = np.array([-0.8, 0.0, 0.0, 0.0])
    pts, nans = _table_and_pillar(base, q0)
    cloud = {"id": "camera", "shape": "points", "points": encode_points(pts),
             "resolution": 0.02}
    # the pillar's own cells, voxelised here: what the plan must stay out of
    pillar = pts[20_000:28_000]
    pillar_cells = (CloudObstacle("pillar", voxelise(pillar[np.isfinite(pillar).all(1)],
                                                     0.02)[0]),)
    scene_file = str(tmp_path / "scene.json")
    srv = start_servers([["--workers", "1", "--scene-file", scene_file]])[0]
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            got = c.request("scene/apply", {"add": [cloud], "state": START})
            counts = got["clouds"]["camera"]
            assert got["state_source"] == "request" and counts["dropped"] == nans
            assert counts["filtered_robot"] >= len(_on_the_robot(base, q0)) - nans
            assert counts["kept"] + counts["dropped"] + counts["filtered_robot"] \
                + counts["filtered_objects"] == len(pts)
            rev = got["revision"]

            plan = c.plan({"start": START, "goal": {"joints": END}, "seed": 3,
                           "planning_time": 5.0})
            assert plan.raw["clouds"] == {"camera": "free"}
            assert plan.raw["scene_revision"] == rev
            qs = _dense(np.array([p["positions"] for p in plan.raw["trajectory"]["points"]]))
            assert np.allclose(qs[-1], [0.8, 0, 0, 0], atol=1e-3)
            assert _hits(base, pillar_cells, qs) == 0
            direct = np.array([[q, 0.0, 0.0, 0.0] for q in np.linspace(-0.8, 0.8, 161)])
            assert _hits(base, pillar_cells, direct) > 0  # the pillar was in the way

            chk = c.request("check", {"joints": {}})  # at 0 the claw is in the pillar
            assert not chk["valid"] and any("camera" in p for p in chk["pairs"])
            assert chk["clouds"] == {"camera": "free"}

            # hostile clouds: coded, naming the field, the scene unchanged
            before = c.request("scene")
            raw = base64.b64encode(np.zeros((4, 3), "<f4").tobytes()).decode()
            nan = base64.b64encode(np.full((5, 3), np.nan, "<f4").tobytes()).decode()
            for change, field in [
                ({**cloud, "points": {"format": "xyz32", "data": raw[:-8]}},
                 "add[0].points.data"),
                ({**cloud, "points": {"format": "xyzrgb", "data": raw}},
                 "add[0].points.format"),
                ({**cloud, "points": {"format": "xyz32", "data": nan}}, "add[0].points"),
                ({**cloud, "frame": "camera_link"}, "add[0].frame"),
            ]:
                with pytest.raises(errors.InvalidRequest) as e:
                    c.request("scene/apply", {"add": [change], "state": START})
                assert e.value.details["field"].startswith(field), (field, e.value)
                assert c.request("scene") == before
            many = {"format": "xyz32",
                    "data": base64.b64encode(bytes(12 * 2_000_001)).decode()}
            with pytest.raises(errors.InvalidRequest) as e:
                c.request("scene/apply", {"add": [{**cloud, "points": many}]})
            assert "limit" in e.value.details
            assert c.request("scene") == before

            # a later add of the same id replaces it (the robot's state: its twin's, at 0)
            wall = np.column_stack([np.full(500, -1.0), np.linspace(-1, 1, 500),
                                    np.full(500, 0.5)])
            again = c.request("scene/apply", {"add": [{**cloud,
                                                       "points": encode_points(wall)}]})
            assert again["revision"] == rev + 1 and again["state_source"] == "robot"
            assert again["clouds"]["camera"]["kept"] == 500
            assert [o["id"] for o in c.request("scene")["objects"]] == ["camera"]
            assert c.request("check", {"joints": {}})["valid"]
    finally:
        srv.stop()
    # a restart keeps the cloud (kept again at the state it was taken)
    srv = start_servers([["--workers", "1", "--scene-file", scene_file]])[0]
    try:
        with PlannerClient(srv.endpoint, timeout=120) as c:
            assert c.request("scene")["revision"] == rev + 1
            far = c.request("check", {"joints": {"joint_1": 1.5}})
            assert far["clouds"] == {"camera": "free"}
    finally:
        srv.stop()


def test_the_scene_add_cloud_command_as_typed(tmp_path):
    import trimesh

    rng = np.random.default_rng(11)
    wall = np.column_stack([np.full(400, -1.0), rng.uniform(-1, 1, 400),
                            rng.uniform(0.2, 1.0, 400)])
    xyz = tmp_path / "wall.xyz"
    xyz.write_text("x y z intensity\n" + "\n".join(f"{x} {y} {z} 7" for x, y, z in wall)
                   + "\nnan nan nan 0\n")
    ply = tmp_path / "wall.ply"
    trimesh.PointCloud(wall + [0.0, 0.0, 0.5]).export(str(ply))
    srv = start_servers([["--workers", "1", "--scene-file", str(tmp_path / "s.json")]])[0]
    con = ["--connect", srv.endpoint]
    try:
        out = run_cli("scene", "add-cloud", "wall", str(xyz), "--resolution", "0.02",
                      "--state", "joint_1=0.3", *con)
        assert out.returncode == 0, out.stderr
        assert "at --state" in out.stdout
        assert "cloud wall: 400 of 401 points kept" in out.stdout, out.stdout
        assert "1 not finite" in out.stdout and "unseen space free" in out.stdout
        out = run_cli("scene", "show", *con)
        assert "wall" in out.stdout and "cells 0.02 m" in out.stdout, out.stdout
        # the same id from a .ply, in a link's frame: the cloud is replaced
        out = run_cli("scene", "add-cloud", "wall", str(ply), "--frame", "base_link",
                      "--pose", "0,0,0.1", *con)
        assert out.returncode == 0 and "revision 2 (1 objects)" in out.stdout, out.stderr
        saved = tmp_path / "cell.json"
        assert run_cli("scene", "save", str(saved), *con).returncode == 0
        out = run_cli("scene", "load", str(saved), *con)
        assert out.returncode == 0 and "revision 3 (1 objects)" in out.stdout, out.stderr
        with PlannerClient(srv.endpoint, timeout=120) as c:
            (obj,) = c.request("scene")["objects"]
            assert obj["state"] == {"joint_1": 0.0, "joint_2": 0.0, "joint_3": 0.0,
                                    "joint_4": 0.0} and obj["frame"] == "base_link"
            # the Python client, as docs/service.md shows it
            applied = c.apply(add=[{"id": "wall", "shape": "points", "resolution": 0.02,
                                    "points": encode_points(read_cloud_file(xyz))}],
                              state={"joint_1": 0.3})
            assert applied.clouds["wall"]["kept"] == 400 and applied.objects == 1
        # refusals: a file that is no cloud, a frame that is no link, occupied without
        # a camera
        bad = tmp_path / "scan.bin"
        bad.write_bytes(b"\0" * 12)
        out = run_cli("scene", "add-cloud", "x", str(bad), *con)
        assert out.returncode != 0 and "scan.bin" in out.stderr, out.stderr
        out = run_cli("scene", "add-cloud", "x", str(xyz), "--frame", "camera_link", *con)
        assert out.returncode == 1 and "add[0].frame" in out.stderr, out.stderr
        out = run_cli("scene", "add-cloud", "x", str(xyz), "--unknown", "occupied", *con)
        assert out.returncode != 0 and "--camera" in out.stderr, out.stderr
    finally:
        srv.stop()
