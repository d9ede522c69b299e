"""`arduinobot view`: its pieces, and the page as headless Chromium renders it."""

from __future__ import annotations

import base64
import io
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import jsonschema
import numpy as np
import pytest
import trimesh
from PIL import Image

from arduinobot.cli.commands.view import read_obstacles
from arduinobot.contract.errors import InvalidRequest
from arduinobot.description.model import rpy_matrix
from arduinobot.planner.planning.goals import JointGoal, NamedGoal
from arduinobot.scene.obstacles import Obstacle
from arduinobot.viewer.geometry import PALETTE, frame_box, matrix_to_wxyz
from arduinobot.viewer.planning import RemoteBackend
from arduinobot.viewer.plots import joint_limits, plot_panels, plot_png
from arduinobot.viewer.trajectory import PlaybackTrajectory, TrajectoryFileError
from tests.helpers.procs import wait_for

ROOT = Path(__file__).resolve().parents[2]
FOLDED = -1.5  # joint_3 [rad]: the forearm folds down into the base (self-collision)


def _traj_json() -> dict:
    # joint_2 goes 0 -> 1 rad in 1 s with zero end velocities
    return {"trajectory": {"joint_names": ["joint_2", "joint_3"], "points": [
        {"positions": [0.0, 0.0], "velocities": [0.0, 0.0], "accelerations": [2.0, 0.0],
         "effort": [1.0, 0.5], "time_from_start": 0.0},
        {"positions": [0.5, 0.0], "velocities": [1.5, 0.0], "accelerations": [0.0, 0.0],
         "effort": [1.0, 0.5], "time_from_start": 0.5},
        {"positions": [1.0, 0.0], "velocities": [0.0, 0.0], "accelerations": [-2.0, 0.0],
         "effort": [1.0, 0.5], "time_from_start": {"sec": 1, "nanosec": 0}},
    ]}, "duration": 1.0}


# -- pieces --------------------------------------------------------------------------
def test_trajectory_json_parses_and_interpolates():
    t = PlaybackTrajectory.from_json(_traj_json())
    assert t.joint_names == ("joint_2", "joint_3")
    assert t.duration == pytest.approx(1.0)
    assert t.at(0.5) == pytest.approx([0.5, 0.0])
    assert t.at(-1.0) == pytest.approx([0.0, 0.0])
    assert t.at(5.0) == pytest.approx([1.0, 0.0])
    mid = t.at(0.25)[0]
    assert 0.0 < mid < 0.5  # Hermite with v(0)=0 starts slower than linear (0.25)
    assert mid < 0.25


@pytest.mark.parametrize("bad, field", [
    ({"joint_names": [], "points": []}, "joint_names"),
    ({"joint_names": ["a"], "points": [{"positions": [0, 1], "time_from_start": 0}]},
     "points[0].positions"),
    ({"joint_names": ["a"], "points": [{"positions": [0], "time_from_start": 1},
                                       {"positions": [1], "time_from_start": 0.5}]},
     "time_from_start"),
    ({"joint_names": ["a"], "points": [{"positions": ["x"], "time_from_start": 0}]},
     "points[0].positions"),
])
def test_trajectory_json_errors_name_the_field(bad, field):
    with pytest.raises(TrajectoryFileError, match=field.replace("[", r"\[").replace("]", r"\]")):
        PlaybackTrajectory.from_json(bad)


def test_frame_box_keeps_every_corner_in_view():
    bounds = np.array([[-0.5, -0.5, 0.0], [0.45, 1.45, 1.7]])
    fov, aspect, fill = math.radians(45), 1.6, 0.9
    v = frame_box(bounds, fov=fov, aspect=aspect, fill=fill, left=0.0)
    pos, at = np.array(v.position), np.array(v.look_at)
    fwd = (at - pos) / np.linalg.norm(at - pos)
    right = np.cross(fwd, (0, 0, 1))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    worst = 0.0
    for c in np.array(np.meshgrid(*bounds.T)).T.reshape(-1, 3):
        d = c - pos
        depth = d @ fwd
        assert depth > 0
        ny = abs(d @ up) / depth / math.tan(fov / 2)
        nx = abs(d @ right) / depth / (math.tan(fov / 2) * aspect)
        worst = max(worst, nx, ny)
    assert worst == pytest.approx(fill, abs=1e-6)  # as close as allowed, no closer
    assert v.position[2] > v.look_at[2]  # looks down on it, +z up


def test_matrix_to_wxyz_round_trips():
    rng = np.random.default_rng(3)
    for rpy in rng.uniform(-math.pi, math.pi, (50, 3)):
        m = rpy_matrix(tuple(rpy))
        w, x, y, z = matrix_to_wxyz(m)
        back = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        assert np.allclose(back, m, atol=1e-9)


def test_palette_has_no_collision_red():
    for r, g, b in PALETTE:
        assert not _is_red(np.array([[[r, g, b]]])).any()


def test_plots_carry_limits_and_render_png(desc):
    t = PlaybackTrajectory.from_json(_traj_json())
    panels = plot_panels(t, joint_limits(desc, t.joint_names))
    assert [p.quantity for p in panels] == ["position", "velocity", "acceleration", "effort"]
    assert panels[0].upper == pytest.approx([math.pi / 2] * 2, abs=1e-4)
    assert panels[1].upper == pytest.approx([10.0, 10.0])
    assert panels[3].lower == pytest.approx([-30.0, -30.0])
    png = plot_png(panels, title="t")
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_remote_request_matches_the_service_schema():
    schema = json.loads((ROOT / "src/arduinobot/contract/schema/plan_request.json").read_text())
    box = Obstacle(id="table", shape="box", size=(1, 1, 0.1), xyz=(0, 0.8, 0.5))
    b = RemoteBackend("tcp/127.0.0.1:1", obstacles=(box,))
    for goal in (NamedGoal("home"), JointGoal({"joint_2": 0.3})):
        jsonschema.validate(b.request(goal, start={"joint_1": 0.0}, group="arm"), schema)


def test_a_mesh_obstacle_is_refused_before_it_reaches_the_service(tmp_path):
    # the wire takes boxes, spheres and cylinders only: a mesh would be refused by the
    # service's schema on every plan, so the backend says so when it is made
    stl = tmp_path / "rock.stl"
    trimesh.creation.icosphere().export(stl)
    rock = Obstacle(id="rock", shape="mesh", mesh_path=str(stl))
    box = Obstacle(id="table", shape="box", size=(1, 1, 0.1))
    with pytest.raises(InvalidRequest, match="'rock' is a mesh") as e:
        RemoteBackend("tcp/127.0.0.1:1", obstacles=(box, rock))
    assert e.value.details["field"] == "obstacles[1].shape"


def test_read_obstacles_from_flags_and_scene(tmp_path):
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"obstacles": [
        {"id": "ball", "shape": "sphere", "radius": 0.1, "xyz": [0, 1, 1]}]}))
    obs = read_obstacles(['{"id": "table", "shape": "box", "size": [1, 1, 0.1]}'], str(scene))
    assert [o.id for o in obs] == ["ball", "table"]
    with pytest.raises(Exception, match=r"--obstacle\[0\]\.size"):
        read_obstacles(['{"id": "t", "shape": "box", "size": [1, -1, 0.1]}'], None)


# -- the page in a real browser ----------------------------------------------------------
def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.fail("headless Chromium is needed for the viewer test: apt-get install -y chromium "
                "(.ci/run installs it)")


class Browser:
    """Headless Chromium driven over the DevTools protocol (websockets, a viser dependency):
    one live page, waited on for what it shows, then captured."""

    def __init__(self, url: str, *, size: tuple[int, int] = (1280, 800)) -> None:
        from websockets.sync.client import connect

        self._profile = tempfile.TemporaryDirectory()
        self.proc = subprocess.Popen(
            [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", f"--user-data-dir={self._profile.name}",
             "--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0",
             "--hide-scrollbars", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            start_new_session=True)  # its helpers in one group, ended together
        ws_url = None
        for line in self.proc.stderr:  # type: ignore[union-attr]
            if "DevTools listening on " in line:
                ws_url = line.split("DevTools listening on ", 1)[1].strip()
                break
        assert ws_url, "chromium did not open its DevTools endpoint"
        self.ws = connect(ws_url, max_size=None, open_timeout=30)
        self._id = 0
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target,
                                 flatten=True)["sessionId"]
        self.call("Emulation.setDeviceMetricsOverride", session=True, width=size[0],
                  height=size[1], deviceScaleFactor=1, mobile=False)
        self.call("Page.navigate", session=True, url=url)

    def call(self, method: str, *, session: bool = False, **params: object) -> dict:
        self._id += 1
        msg: dict = {"id": self._id, "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        self.ws.send(json.dumps(msg))
        while True:
            reply = json.loads(self.ws.recv(timeout=120))
            if reply.get("id") == self._id:
                assert "error" not in reply, f"{method}: {reply['error']}"
                return reply["result"]

    def eval(self, expr: str) -> object:
        r = self.call("Runtime.evaluate", session=True, expression=expr, awaitPromise=True,
                      returnByValue=True)
        return r["result"].get("value")

    def wait_text(self, text: str, *, timeout: float = 90.0) -> None:
        """Wait until the page shows ``text`` (the server's state has arrived)."""
        deadline = time.monotonic() + timeout
        probe = f"!!document.body && document.body.innerText.includes({json.dumps(text)})"
        while not self.eval(probe):
            assert time.monotonic() < deadline, f"the page never showed {text!r}"
            time.sleep(0.2)

    def capture(self) -> np.ndarray:
        """The page now, after the canvas drew a couple more frames, as (h, w, 3) uint8."""
        assert self.eval("document.querySelectorAll('canvas').length") >= 1, "no 3D canvas"
        self.eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        data = self.call("Page.captureScreenshot", session=True, format="png")["data"]
        return np.asarray(Image.open(io.BytesIO(base64.b64decode(data))).convert("RGB"))

    def screenshot(self, out: Path, *, timeout: float = 60.0) -> np.ndarray:
        """Capture once the picture has settled (the page fades the scene in over a moment
        of wall-clock time): two captures 0.3 s apart that agree. Saved to ``out``."""
        deadline = time.monotonic() + timeout
        prev = self.capture()
        while True:
            time.sleep(0.3)
            img = self.capture()
            if np.abs(img.astype(int) - prev).mean() < 0.2:
                break
            assert time.monotonic() < deadline, "the page never settled"
            prev = img
        Image.fromarray(img).save(out)
        return img

    def close(self) -> None:
        self.ws.close()
        self.proc.terminate()
        self.proc.wait(timeout=30)
        # Chromium's helper processes outlive the browser for a moment and still write
        # to the profile: end the group and wait until none is left before removing it
        wait_for(lambda: not _group_alive(self.proc.pid), timeout=30,
                 what="Chromium's helper processes to exit")
        self._profile.cleanup()


def _group_alive(pgid: int) -> bool:
    """Whether a live (not zombie) process of group ``pgid`` is left; each is asked to end."""
    alive = False
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            # after the command's ")": state, ppid, pgrp, ...
            state, _ppid, pgrp = stat.read_text().rsplit(")", 1)[1].split()[:3]
        except (OSError, IndexError):  # ended while we read
            continue
        if int(pgrp) == pgid and state != "Z":
            alive = True
            try:
                os.kill(int(stat.parent.name), signal.SIGTERM)
            except ProcessLookupError:  # it ended between the read and the signal: done
                pass
    return alive


def _scene_region(img: np.ndarray) -> np.ndarray:
    # left of the floating control panel, below the software-rendering notice
    h, w, _ = img.shape
    return img[int(0.2 * h):int(0.97 * h), int(0.1 * w):int(0.72 * w)].astype(int)


def _is_red(img: np.ndarray) -> np.ndarray:
    r, g, b = img[..., 0].astype(int), img[..., 1].astype(int), img[..., 2].astype(int)
    return (r > 130) & (r > 2 * g) & (r > 2 * b)


def _coloured(img: np.ndarray) -> np.ndarray:
    # the links are saturated colours; the page, grid and shadows are greys
    return (img.max(axis=-1) - img.min(axis=-1)) > 45


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_page_shows_robot_and_collision_in_chromium(desc, tmp_path):
    from arduinobot.viewer.app import RobotViewer
    from arduinobot.viewer.playback import PlaybackPanel

    viewer = RobotViewer(desc, port=_free_port())
    playback = PlaybackPanel(viewer)
    browser = None
    try:
        browser = Browser(viewer.url)
        browser.wait_text("No collision")
        home = _scene_region(browser.screenshot(tmp_path / "home.png"))
        coloured = _coloured(home)
        assert coloured.mean() > 0.04, f"only {coloured.mean():.1%} robot pixels: blank page?"
        ys, _ = np.nonzero(coloured)
        # framed: the robot spans most of the scene region's height
        assert (ys.max() - ys.min()) > 0.5 * home.shape[0]
        assert _is_red(home).mean() < 1e-4  # nothing collides at zero

        before = viewer.link_poses()
        viewer.sliders["joint_3"].value = FOLDED  # what dragging the slider does
        assert viewer.q[2] == pytest.approx(FOLDED)
        assert not np.allclose(viewer.link_poses(), before)
        assert not viewer.check.valid
        assert ("base_link", "claw_support") in viewer.check.pairs

        browser.wait_text("In collision")  # the live page got the update
        folded = _scene_region(browser.screenshot(tmp_path / "folded.png"))
        changed = (np.abs(folded - home).sum(axis=-1) > 60).mean()
        assert changed > 0.02, f"only {changed:.1%} of pixels changed after the slider moved"
        assert _is_red(folded).mean() > 0.005, "no red collision pixels after folding the arm"

        # playback drives the same pose: scrubbing a loaded trajectory moves joint_2
        playback.load(PlaybackTrajectory.from_json(_traj_json()))
        playback._scrub.value = 0.5
        assert viewer.q[1] == pytest.approx(0.5)
        assert viewer.q[2] == pytest.approx(0.0)  # the trajectory's joint_3 column
        assert viewer.check.valid
    finally:
        if browser is not None:
            browser.close()
        playback.close()
        viewer.close()
