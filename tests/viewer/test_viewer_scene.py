"""Issue 28 item 3: the viewer draws the kept scene (boxes, spheres, cylinders, meshes by
their data) in the world and carried objects on their link, follows the service's scene
as it changes, and the PNG still draws it too."""

from __future__ import annotations

import base64
import io
import json
import subprocess
import sys
import time

import numpy as np
import pytest
import trimesh
from PIL import Image

from arduinobot.client.client import PlannerClient
from arduinobot.contract.errors import InvalidRequest
from arduinobot.planner.kinematics.chain import Kinematics
from arduinobot.viewer.geometry import CARRIED_RGB, link_meshes
from arduinobot.viewer.scene_view import NO_REVISION, ViewerScene, read_scene_file
from arduinobot.viewer.still import still_bodies, still_png
from tests.helpers.fk import link_pose
from tests.helpers.serve import REPO, free_port, start_server

JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4")
# a 1 x 2 x 3 box as binary STL, drawn at a tenth of its size
MESH = base64.b64encode(trimesh.creation.box(extents=(1, 2, 3)).export(file_type="stl")).decode()
TABLE = {"id": "table", "shape": "box", "size": [1, 1, 0.1], "xyz": [0, 1, 0.5]}
BALL = {"id": "ball", "shape": "sphere", "radius": 0.05, "xyz": [0.3, -0.4, 0.3]}
CAN = {"id": "can", "shape": "cylinder", "radius": 0.05, "length": 0.2, "xyz": [-0.3, 0.3, 0.3],
       "rpy": [0, 0, 0.5]}
BIN = {"id": "bin", "shape": "mesh", "xyz": [0.5, -0.5, 0.2], "rpy": [0, 0, 1.0], "scale": 0.1,
       "mesh": {"format": "stl", "data": MESH}}
# carried: 20 cm out along the claw's z axis, in its frame
CUP = {"object": {"id": "cup", "shape": "box", "size": [0.06, 0.06, 0.06], "xyz": [0, 0, 0.2]},
       "link": "claw_support", "mass": 0.1}
BENT = {"joint_1": 0.8, "joint_2": 0.4, "joint_3": -0.3, "joint_4": 0.0}


def _scene(revision=3, objects=(TABLE, BALL, CAN, BIN), attached=(CUP,)):
    return {"revision": revision, "objects": list(objects), "attached": list(attached)}


def _q(values) -> np.ndarray:
    return np.array([values[n] for n in JOINTS])


def _world(desc, link: str, values) -> np.ndarray:
    """The link's pose by the tests' own FK walk (not the viewer's kinematics)."""
    return link_pose(desc.robot, link, JOINTS, _q(values))


def test_a_scene_reads_into_what_is_drawn(desc, tmp_path):
    s = ViewerScene.from_json(_scene(), desc, source="test", mesh_dir=tmp_path)
    assert s.revision == 3
    assert [(i.id, i.link) for i in s.items] == [
        ("table", None), ("ball", None), ("can", None), ("bin", None), ("cup", "claw_support")]
    items = {i.id: i for i in s.items}
    # each shape's own extent, in its own frame
    ext = {k: i.vertices.max(axis=0) - i.vertices.min(axis=0) for k, i in items.items()}
    assert ext["table"] == pytest.approx([1, 1, 0.1], abs=1e-6)
    assert ext["ball"] == pytest.approx([0.1] * 3, abs=2e-3)
    assert ext["can"] == pytest.approx([0.1, 0.1, 0.2], abs=2e-3)
    assert ext["bin"] == pytest.approx([0.1, 0.2, 0.3], abs=1e-6)  # the mesh's data, scaled
    # a free object's pose is its own; yaw 1.0 of the bin's
    assert items["bin"].pose()[:3, 3] == pytest.approx([0.5, -0.5, 0.2])
    assert items["bin"].pose()[:2, 0] == pytest.approx([np.cos(1.0), np.sin(1.0)])
    # a carried one is where its link is
    claw = _world(desc, "claw_support", BENT)
    assert np.allclose(items["cup"].pose(claw), claw @ items["cup"].offset)
    assert items["cup"].offset[:3, 3] == pytest.approx([0, 0, 0.2])
    with pytest.raises(ValueError, match="carried by 'claw_support'"):
        items["cup"].pose()
    # what the collision check takes: the free objects and the carried one
    assert [o.id for o in s.obstacles] == ["table", "ball", "can", "bin"]
    assert [(a.id, a.link) for a in s.attached] == [("cup", "claw_support")]
    assert "revision 3: 4 object(s), carried: cup by claw_support" in s.summary()


def test_a_scene_this_model_cannot_show_is_refused_naming_the_field(desc, tmp_path):
    bad = {**CUP, "link": "wrist_of_another_robot"}
    with pytest.raises(InvalidRequest) as e:
        ViewerScene.from_json(_scene(attached=[bad]), desc, mesh_dir=tmp_path)
    assert e.value.details["field"] == "attached[0]"
    with pytest.raises(InvalidRequest) as e:
        ViewerScene.from_json(_scene(objects=[{**TABLE, "size": [1, -1, 1]}]), desc,
                              mesh_dir=tmp_path)
    assert e.value.details["field"] == "objects[0].size"
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(_scene(attached=[bad])))
    with pytest.raises(InvalidRequest, match=f"scene file {path}"):
        read_scene_file(str(path), desc)


def test_an_object_fixed_to_a_link_is_drawn_on_it(desc, tmp_path):
    cam = {"id": "cam", "shape": "box", "size": [0.05] * 3, "xyz": [0, 0.2, 0.3],
           "frame": "claw_support"}
    s = ViewerScene.from_json(_scene(objects=(TABLE, cam), attached=()), desc,
                              mesh_dir=tmp_path)
    items = {i.id: i for i in s.items}
    assert (items["cam"].link, items["cam"].fixed) == ("claw_support", True)
    claw = _world(desc, "claw_support", BENT)
    assert items["cam"].pose(claw)[:3, 3] == pytest.approx((claw @ [0, 0.2, 0.3, 1])[:3])
    # the collision check carries it with its link
    assert [o.id for o in s.obstacles] == ["table"]
    assert [(a.id, a.link, a.mass) for a in s.attached] == [("cam", "claw_support", 0.0)]
    assert "2 object(s), fixed to links: cam on claw_support" in s.summary()


def test_changes_name_what_to_draw_anew_and_what_goes(desc, tmp_path):
    before = ViewerScene.from_json(_scene(), desc, mesh_dir=tmp_path)
    moved = {**TABLE, "xyz": [0, 1, 0.4]}
    after = ViewerScene.from_json(_scene(4, (moved, BALL, BIN), ()), desc, mesh_dir=tmp_path)
    fresh, gone = after.changes(before)
    assert fresh == ("table",)
    assert set(gone) == {"table", "can", "cup"}
    assert after.changes(after) == ((), ())
    assert ViewerScene().revision == NO_REVISION and ViewerScene().summary() == "no kept scene"


def test_the_page_draws_the_scene_and_carries_the_cup_with_its_link(desc, tmp_path):
    from arduinobot.viewer.app import RobotViewer

    scene = ViewerScene.from_json(_scene(), desc, mesh_dir=tmp_path)
    page = RobotViewer(desc, scene=scene, port=free_port())
    try:
        assert set(page._scene_handles) == {"table", "ball", "can", "bin", "cup"}
        cup = next(i for i in scene.items if i.id == "cup")
        for values in ({n: 0.0 for n in JOINTS}, BENT):
            page.set_joints(values)
            want = _world(desc, "claw_support", values) @ cup.offset
            assert np.allclose(page.object_poses()["cup"], want, atol=1e-9)
            h = page._scene_handles["cup"]
            assert np.allclose(h.position, want[:3, 3], atol=1e-6)  # what the page shows
        table = page.object_poses()["table"]
        assert table[:3, 3] == pytest.approx([0, 1, 0.5])  # the world's stay put
        # the collision check has the scene: a box over the base turns both red
        over = {"id": "crate", "shape": "box", "size": [0.3, 0.3, 0.3], "xyz": [0, 0, 0.1]}
        fresh, gone = page.set_scene(ViewerScene.from_json(
            _scene(4, (TABLE, BALL, CAN, BIN, over)), desc, mesh_dir=tmp_path))
        assert (fresh, gone) == (("crate",), ())
        assert any("crate" in pair for pair in page.check.pairs)
        assert tuple(page._scene_handles["crate"].color) == (225, 25, 25)
        # removed and detached: gone from the page and from the check
        page.set_scene(ViewerScene.from_json(_scene(5, (TABLE,), ()), desc, mesh_dir=tmp_path))
        assert set(page._scene_handles) == {"table"}
        assert page.check.valid
        assert "revision 5: 1 object(s)" in page._scene_md.content
    finally:
        page.close()


def _magenta(png: bytes) -> np.ndarray:
    """Where a PNG shows the carried colour (shaded: a darker or lighter magenta)."""
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 80) & (abs(r - b) < 30) & (r > 2 * g)


def test_the_png_draws_the_scene_and_the_cup_where_its_link_is(desc, tmp_path):
    kin = Kinematics(desc.robot)
    meshes = link_meshes(desc, kin)
    scene = ViewerScene.from_json(_scene(objects=(TABLE,)), desc, mesh_dir=tmp_path)
    bodies = still_bodies(kin, meshes, np.zeros(kin.dof), scene=scene)
    assert [b.name for b in bodies][-2:] == ["table", "cup"]
    assert bodies[-1].color == CARRIED_RGB
    cup = bodies[-1].triangles.reshape(-1, 3).mean(axis=0)
    claw = _world(desc, "claw_support", {n: 0.0 for n in JOINTS})
    assert cup == pytest.approx((claw @ [0, 0, 0.2, 1])[:3], abs=1e-6)
    bent = still_bodies(kin, meshes, _q(BENT), scene=scene)
    bent_cup = bent[-1].triangles.reshape(-1, 3).mean(axis=0)
    assert bent_cup == pytest.approx((_world(desc, "claw_support", BENT) @ [0, 0, 0.2, 1])[:3],
                                     abs=1e-6)
    # in the picture: magenta where the cup is, none without a scene, elsewhere when bent
    at_zero, at_bent = _magenta(still_png(bodies)), _magenta(still_png(bent))
    assert at_zero.sum() > 100 and at_bent.sum() > 100
    assert _magenta(still_png(still_bodies(kin, meshes, np.zeros(kin.dof)))).sum() == 0
    ys0, xs0 = np.nonzero(at_zero)
    ys1, xs1 = np.nonzero(at_bent)
    assert np.hypot(xs0.mean() - xs1.mean(), ys0.mean() - ys1.mean()) > 20


# -- through a real service -------------------------------------------------------------
@pytest.fixture(scope="module")
def served():
    srv = start_server(["--workers", "1"])
    try:
        with PlannerClient(srv.endpoint, timeout=60) as c:
            yield srv, c
    finally:
        srv.stop()


def _wait(cond, what: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


@pytest.mark.slow
def test_the_page_follows_the_services_scene(served, desc):
    from arduinobot.viewer.app import RobotViewer
    from arduinobot.viewer.scene_follow import SceneFollower

    srv, c = served
    c.request("scene/apply", {"clear": True})
    page = RobotViewer(desc, port=free_port())
    # a long poll: each change below is drawn because the service published it
    follower = SceneFollower(page, c, poll=60.0)
    try:
        rev = c.request("scene/apply", {"add": [TABLE, BIN]})["revision"]
        _wait(lambda: page.scene.revision == rev, "the added objects")
        assert set(page._scene_handles) == {"table", "bin"}
        bin_item = next(i for i in page.scene.items if i.id == "bin")
        assert bin_item.vertices.max(axis=0) - bin_item.vertices.min(axis=0) == \
            pytest.approx([0.1, 0.2, 0.3], abs=1e-6)  # the mesh, by its data
        # the cup is taken where it stands, with the arm bent: carried from there on
        cup_world = {**CUP["object"], "xyz": [0.4, -0.3, 0.9]}
        c.request("scene/apply", {"add": [cup_world]})
        rev = c.request("scene/apply", {"remove": ["table"], "state": BENT,
                                        "attach": [{"object": "cup", "link": "claw_support",
                                                    "mass": 0.1}]})["revision"]
        _wait(lambda: page.scene.revision == rev, "the attach")
        assert set(page._scene_handles) == {"bin", "cup"}
        assert [(a.id, a.link) for a in page.scene.attached] == [("cup", "claw_support")]
        held = np.eye(4)
        held[:3, 3] = cup_world["xyz"]
        page.set_joints(BENT)  # where it was taken, it is where it stood
        assert np.allclose(page.object_poses()["cup"], held, atol=1e-9)
        home = {n: 0.0 for n in JOINTS}
        page.set_joints(home)  # and it moves with the claw
        want = _world(desc, "claw_support", home) @ np.linalg.inv(
            _world(desc, "claw_support", BENT)) @ held
        assert np.allclose(page.object_poses()["cup"], want, atol=1e-9)
        assert np.allclose(page._scene_handles["cup"].position, want[:3, 3], atol=1e-6)
        assert not np.allclose(want[:3, 3], held[:3, 3], atol=0.05)
        # put down and removed: followed too
        c.request("scene/apply", {"detach": ["cup"], "state": home})
        rev = c.request("scene/apply", {"remove": ["cup"]})["revision"]
        _wait(lambda: page.scene.revision == rev, "the detach and remove")
        assert set(page._scene_handles) == {"bin"} and not page.scene.attached
        assert follower.shown[-1] == rev
        assert follower.shown == sorted(follower.shown)
    finally:
        follower.close()
        page.close()


@pytest.mark.slow
def test_a_missed_publication_is_caught_by_the_health_poll(served, desc, monkeypatch):
    from arduinobot.viewer.app import RobotViewer
    from arduinobot.viewer.scene_follow import SceneFollower

    srv, c = served
    c.request("scene/apply", {"clear": True})
    asked: list[str] = []
    request = c.request

    def counted(key, *args, **kw):
        asked.append(key)
        return request(key, *args, **kw)

    monkeypatch.setattr(c, "request", counted)
    page = RobotViewer(desc, port=free_port())
    follower = SceneFollower(page, c, poll=0.2)
    try:
        _wait(lambda: follower.shown, "the first read")
        # from here on, every publication is missed (the follower listens elsewhere)
        follower._sub.undeclare()
        follower._sub = c.session.declare_subscriber("elsewhere/x", lambda _s: None)
        rev = request("scene/apply", {"add": [BALL]})["revision"]
        assert request("health")["scene_revision"] == rev
        _wait(lambda: page.scene.revision == rev, "the polled change")
        assert set(page._scene_handles) == {"ball"}
        time.sleep(0.3)
        asked.clear()
        time.sleep(1.0)  # ~5 polls at the same revision: health only, no scene read
        assert asked.count("health") >= 3 and "scene" not in asked, asked
    finally:
        follower.close()
        page.close()


@pytest.mark.slow
def test_view_png_draws_the_services_scene_with_the_carried_cup(served, tmp_path):
    srv, c = served
    c.request("scene/apply", {"clear": True, "add": [TABLE, {**CUP["object"], "xyz": [0.4, -0.3, 0.9]}]})
    rev = c.request("scene/apply", {"state": BENT, "attach": [
        {"object": "cup", "link": "claw_support"}]})["revision"]
    out = tmp_path / "still.png"
    r = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "view", "--connect", srv.endpoint,
                        "--png", str(out)], cwd=REPO, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"scene revision {rev}: 1 object(s), carried: cup by claw_support" in r.stdout
    assert _magenta(out.read_bytes()).sum() > 100


def test_an_obstacle_and_a_scene_object_of_one_id_are_refused_by_name(desc, tmp_path):
    from arduinobot.scene.obstacles import Obstacle
    from arduinobot.viewer.app import RobotViewer

    scene = ViewerScene.from_json(_scene(), desc, mesh_dir=tmp_path)
    table = Obstacle.from_mapping({**TABLE, "xyz": [0, 2, 0.5]})
    with pytest.raises(InvalidRequest, match=r"id\(s\) table name both an obstacle .* "
                       r"kept scene \(revision 3"):
        RobotViewer(desc, obstacles=(table,), scene=scene, port=free_port())


def test_view_png_of_a_saved_scene_and_no_saved_scene_with_connect(tmp_path, capsys):
    from arduinobot.cli.main import main

    cell, out = tmp_path / "cell.json", tmp_path / "cell.png"
    cell.write_text(json.dumps(_scene(objects=(TABLE, BIN))))
    assert main(["view", "--local", "--scene", str(cell), "--png", str(out)]) == 0
    said = capsys.readouterr().out
    assert "scene revision 3: 2 object(s), carried: cup by claw_support (cell.json)" in said
    assert _magenta(out.read_bytes()).sum() > 100
    # a saved scene is this process's: the service plans around its own
    with pytest.raises(SystemExit) as e:
        main(["view", "--connect", "tcp/127.0.0.1:1", "--scene", str(cell), "--png",
              str(out)])
    assert e.value.code == 2
    assert "is a kept scene: the service plans around its own" in capsys.readouterr().err


def test_in_process_plans_go_around_the_pages_kept_scene_and_what_it_carries(desc, tmp_path):
    from arduinobot.contract.errors import GoalInCollision
    from arduinobot.planner.planning.goals import JointGoal
    from arduinobot.viewer.planning import LocalBackend

    # a crate 30 cm out along the claw's z axis at BENT: the arm misses it, a cup carried
    # there does not
    spot = _world(desc, "claw_support", BENT) @ [0, 0, 0.3, 1]
    crate = {"id": "crate", "shape": "box", "size": [0.06] * 3, "xyz": [float(v) for v in spot[:3]]}
    cup = {**CUP, "object": {**CUP["object"], "xyz": [0, 0, 0.3]}}
    shown = {"scene": ViewerScene.from_json(_scene(objects=(crate,), attached=()), desc,
                                            mesh_dir=tmp_path)}
    backend = LocalBackend(desc, scene=lambda: shown["scene"])
    start = {n: 0.0 for n in JOINTS}
    traj = backend.plan(JointGoal(BENT), start=start, group="all")
    assert traj.positions[-1] == pytest.approx(_q(BENT), abs=1e-6)
    # the page's scene at the next plan: now carrying the cup
    shown["scene"] = ViewerScene.from_json(_scene(objects=(crate,), attached=(cup,)), desc,
                                           mesh_dir=tmp_path)
    with pytest.raises(GoalInCollision) as e:
        backend.plan(JointGoal(BENT), start=start, group="all")
    assert ("cup", "crate") in e.value.pairs or ("crate", "cup") in e.value.pairs


def test_view_png_at_a_time_of_the_trajectory_carries_the_cup_there(tmp_path, capsys):
    from arduinobot.cli.main import main

    cell, traj = tmp_path / "cell.json", tmp_path / "traj.json"
    cell.write_text(json.dumps(_scene(objects=(TABLE,))))
    # joint_1 (the base's turn) 0 -> 1 rad in 1 s
    traj.write_text(json.dumps({"trajectory": {"joint_names": ["joint_1"], "points": [
        {"positions": [0.0], "velocities": [0.0], "time_from_start": 0.0},
        {"positions": [1.0], "velocities": [0.0], "time_from_start": 1.0}]}}))
    where = {}
    for at in ("0", "1"):
        out = tmp_path / f"at{at}.png"
        assert main(["view", "--local", "--scene", str(cell), "--trajectory", str(traj),
                     "--at", at, "--png", str(out)]) == 0
        ys, xs = np.nonzero(_magenta(out.read_bytes()))
        assert len(xs) > 50, at
        where[at] = (xs.mean(), ys.mean())
    capsys.readouterr()
    assert np.hypot(where["0"][0] - where["1"][0], where["0"][1] - where["1"][1]) > 20


@pytest.mark.slow
def test_the_page_in_chromium_shows_the_cup_moving_with_the_claw(desc, tmp_path):
    from arduinobot.viewer.app import RobotViewer
    from tests.viewer.test_viewer import Browser, _scene_region

    big = {**CUP, "object": {**CUP["object"], "size": [0.1, 0.1, 0.1]}}
    scene = ViewerScene.from_json(_scene(objects=(TABLE,), attached=(big,)), desc,
                                  mesh_dir=tmp_path)
    page = RobotViewer(desc, scene=scene, port=free_port())
    browser = None
    try:
        browser = Browser(page.url)
        browser.wait_text("carried: cup by claw_support")
        spots = []
        for k, values in enumerate(({n: 0.0 for n in JOINTS}, BENT)):
            page.set_joints(values)
            img = _scene_region(browser.screenshot(tmp_path / f"page{k}.png")).astype(np.uint8)
            buf = io.BytesIO()
            Image.fromarray(img).save(buf, format="png")
            ys, xs = np.nonzero(_magenta(buf.getvalue()))
            assert len(xs) > 50, f"no carried cup on the page at {values}"
            spots.append((xs.mean(), ys.mean()))
        (x0, y0), (x1, y1) = spots
        assert np.hypot(x1 - x0, y1 - y0) > 20, "the cup did not move with the claw"
    finally:
        if browser is not None:
            browser.close()
        page.close()


def _tan(png: bytes) -> int:
    """How many pixels show the kept scene's colour (SCENE_RGB, shaded: its hue)."""
    from arduinobot.viewer.geometry import SCENE_RGB
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(float)
    total = img.sum(axis=2)
    want = np.asarray(SCENE_RGB, float) / sum(SCENE_RGB)
    return int(((np.abs(img / np.maximum(total, 1)[..., None] - want).max(axis=2) < 0.02)
                & (total > 60)).sum())


def test_view_png_shows_what_stands_on_a_table(tmp_path, capsys):
    """A box on a table (issue 38, item 9): each body was its own collection, sorted by
    its centre, so the table's was drawn over the box's."""
    from arduinobot.cli.main import main
    cell = tmp_path / "cell.json"
    cell.write_text(json.dumps({"revision": 1, "objects": [
        {"id": "box", "shape": "box", "size": [0.08, 0.08, 0.08], "xyz": [0.52, 0.8, 0.39]}]}))
    table = json.dumps({"id": "table", "shape": "box", "size": [0.5, 0.5, 0.05],
                        "xyz": [0.52, 0.8, 0.325]})
    alone, on_table = tmp_path / "alone.png", tmp_path / "on_table.png"
    assert main(["view", "--local", "--scene", str(cell), "--png", str(alone)]) == 0
    assert main(["view", "--local", "--scene", str(cell), "--obstacle", table,
                 "--png", str(on_table)]) == 0
    capsys.readouterr()
    seen_alone = _tan(alone.read_bytes())
    assert seen_alone > 100  # the box as drawn with nothing under it
    # on the table, its top and two sides still show (its bottom face is the table's)
    assert _tan(on_table.read_bytes()) > 0.6 * seen_alone


def _cloud_object(cid="camera", at=(0.55, -0.05, 0.25)):
    # a measured 10 x 10 x 50 cm pillar centred at `at`, 4 cm cells: its points as xyz32
    from arduinobot.scene.cloud import encode_points
    rng = np.random.default_rng(8)
    pts = np.asarray(at) + rng.uniform([-0.05, -0.05, -0.25], [0.05, 0.05, 0.25], (4000, 3))
    return {"id": cid, "shape": "points", "resolution": 0.04, "points": encode_points(pts),
            "state": {n: 0.0 for n in JOINTS}}


def test_a_cloud_is_drawn_as_its_cells_coloured_by_height(desc, tmp_path):
    from arduinobot.viewer.geometry import height_colors

    s = ViewerScene.from_json(_scene(objects=(TABLE, _cloud_object()), attached=()), desc,
                              mesh_dir=tmp_path)
    [cloud] = s.clouds
    assert cloud.id == "camera" and cloud.size == 0.04
    [body] = s.cloud_bodies
    np.testing.assert_allclose(cloud.points, body.cells.centers, atol=1e-6)
    # every centre on the 4 cm grid, inside the measured pillar's extent
    assert ((cloud.points >= [0.48, -0.12, -0.02]) & (cloud.points <= [0.62, 0.02, 0.52])).all()
    z = cloud.points[:, 2]
    low, high = cloud.colors[np.argmin(z)], cloud.colors[np.argmax(z)]
    assert low[2] > low[0] and high[0] > high[2]  # blue at the bottom, red at the top
    assert tuple(height_colors(np.array([1.0, 1.0]))[0]) == tuple(height_colors(np.zeros(1))[0])
    assert "clouds: camera (" in s.summary()
    again = ViewerScene.from_json(_scene(4, (TABLE, _cloud_object()), ()), desc,
                                  mesh_dir=tmp_path)
    assert again.changes(s) == ((), ())  # the same cells: nothing drawn anew
    gone = ViewerScene.from_json(_scene(5, (TABLE,), ()), desc, mesh_dir=tmp_path)
    assert gone.changes(s) == ((), ("camera",))


def test_the_page_draws_a_cloud_and_checks_against_it(desc, tmp_path):
    from arduinobot.viewer.app import RobotViewer

    scene = ViewerScene.from_json(_scene(objects=(TABLE,), attached=()), desc,
                                  mesh_dir=tmp_path)
    page = RobotViewer(desc, scene=scene, port=free_port())
    try:
        # the pillar where the claw is at joint_1 = 0 (the tests' own FK walk)
        reach = {"joint_1": 0.0, "joint_2": 0.9, "joint_3": 0.6, "joint_4": 0.0}
        claw = _world(desc, "claw_support", reach)[:3, 3]
        with_cloud = ViewerScene.from_json(_scene(4, (TABLE, _cloud_object(at=claw)), ()),
                                           desc, mesh_dir=tmp_path)
        assert page.set_scene(with_cloud) == (("camera",), ())
        h = page._scene_handles["camera"]
        np.testing.assert_allclose(h.points, with_cloud.clouds[0].points, atol=1e-6)
        np.testing.assert_array_equal(h.colors, with_cloud.clouds[0].colors)
        assert h.point_size == pytest.approx(0.04)
        # the page's collision check has the cloud: swung into the pillar, the arm is red
        hits = []
        for a in (0.0, np.pi / 2):
            page.set_joints({**reach, "joint_1": a})
            hits.append(any("camera" in pair for pair in page.check.pairs))
        assert hits == [True, False]
        page.set_scene(ViewerScene.from_json(_scene(5, (TABLE,), ()), desc, mesh_dir=tmp_path))
        assert set(page._scene_handles) == {"table"}
    finally:
        page.close()
