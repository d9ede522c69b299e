"""``serve --ros2 --cloud-topic`` and ``--camera-topic`` (issue 40 item 4, issue 41 item
2) on the course's workspace (its RGB camera on a fixed joint to base_link), fed by an
independent publisher with none of our ``ros2`` package (tests/helpers/ros2_publish.py:
raw Zenoh puts on rmw_zenoh's key, rosbags' CDR, the attachment by hand), and the
client's ``perceive``."""

from __future__ import annotations

import json
import math
import re
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import yaml
import zenoh

from arduinobot.client import errors as cerr
from arduinobot.client.client import PlannerClient
from arduinobot.description import load_description
from arduinobot.planner.planning.pipeline import MotionPlanner
from arduinobot.scene.cloud import CloudObstacle, decode_points, posed, voxelise
from tests.helpers.cli import run_cli
from tests.helpers.fk import link_pose
from tests.helpers.ros2_publish import DesignPublisher, T, cloud, header
from tests.helpers.serve import start_server
from tests.ros2.test_ros2_zenoh import wait_for
from tests.scene.test_scene_cloud import _hits

pytestmark = pytest.mark.slow  # starts serve

DOMAIN = 23
CLOUDS, IMAGES = "/camera/points", "/camera/image_raw"
CAMERA = "rgb_camera_link"
RES = 0.02


@pytest.fixture(scope="module")
def served(course_ws, tmp_path_factory) -> Iterator[tuple[Any, zenoh.Session]]:
    srv = start_server(["--workers", "1", str(course_ws.xacro), "--package-dir",
                        str(course_ws.src), "--moveit-config", str(course_ws.moveit_pkg),
                        "--scene-file", str(tmp_path_factory.mktemp("in") / "scene.json"),
                        "--ros2", "--ros-domain-id", str(DOMAIN),
                        "--cloud-topic", CLOUDS, "--cloud-rate", "5", "--cloud-id", "camera",
                        "--cloud-resolution", str(RES), "--camera-topic", IMAGES],
                       timeout=300)
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([srv.endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    try:
        yield srv, session
    finally:
        session.close()
        srv.stop()


def _subscribed(session: zenoh.Session, topic: str) -> str:
    """The data key of our subscription to ``topic``, from its liveliness token."""
    for r in session.liveliness().get(f"@ros2_lv/{DOMAIN}/**", timeout=3):
        chunks = str(r.ok.key_expr).split("/") if r.ok is not None else []
        if len(chunks) == 13 and chunks[5] == "MS" and chunks[9].replace("%", "/") == topic:
            return f"{DOMAIN}/{topic.strip('/')}/{chunks[10]}/{chunks[11]}"
    raise AssertionError(f"no subscription to {topic} on the graph")


def _pillar_at_the_claw(robot: Any, names: list[str]) -> np.ndarray:
    """World points filling a box around the gripper at joint_1 = 0.8 rad (far from the
    arm where the twin rests, at 0), 1 cm apart, seeded jitter."""
    rng = np.random.default_rng(5)
    tips = [link_pose(robot, link, names, np.array([0.8, 0, 0, 0]))[:3, 3]
            for link in ("gripper_left", "gripper_right", "claw_support")]
    lo, hi = np.min(tips, axis=0) - 0.04, np.max(tips, axis=0) + 0.04
    axes = [np.arange(a, b, 0.01) for a, b in zip(lo, hi)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return grid + rng.uniform(-0.002, 0.002, grid.shape)


def test_a_pointcloud2_reaches_the_kept_scene_in_the_cameras_frame(served, course_ws):
    srv, session = served
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src])
    names = list(d.robot.actuated_joints)
    cam = link_pose(d.robot, CAMERA, names, np.zeros(len(names)))  # a fixed joint: any state
    world = _pillar_at_the_claw(d.robot, names)
    in_cam = posed(world, np.linalg.inv(cam)).astype(np.float32)
    pts = np.vstack([in_cam, np.full((7, 3), np.nan, np.float32)])  # a depth camera's holes
    pub = DesignPublisher(session, DOMAIN, CLOUDS, "sensor_msgs/msg/PointCloud2")
    assert _subscribed(session, CLOUDS) == pub.key  # our token's key is rmw_zenoh's
    with PlannerClient(srv.endpoint, timeout=120) as c:
        before = c.request("scene")["revision"]

        def kept() -> bool:
            objects = c.request("scene")["objects"]
            return any(o["id"] == "camera" for o in objects)
        end = time.monotonic() + 120
        while not kept() and time.monotonic() < end:
            pub.put(cloud(pts, CAMERA))  # until the subscription's route is in place
            wait_for(kept, 3.0)
        scene = c.request("scene")
        (obj,) = [o for o in scene["objects"] if o["id"] == "camera"]
        assert scene["revision"] > before
        assert obj["shape"] == "points" and obj["frame"] == CAMERA
        assert obj["resolution"] == RES
        sent = decode_points(obj["points"])
        np.testing.assert_array_equal(sent.points, in_cam.astype(np.float64))  # NaN dropped

        # the cells where the camera's FK puts them: the arm at joint_1 0.8 is in them,
        # at -0.8 it is clear; the points taken as world coordinates (the frame ignored)
        # would not be in its way
        base = MotionPlanner(load_description()).context.world(())
        cells = (CloudObstacle("camera", voxelise(posed(in_cam.astype(np.float64), cam),
                                                  RES)[0]),)
        unplaced = (CloudObstacle("camera", voxelise(in_cam.astype(np.float64), RES)[0]),)
        hit, clear = np.array([[0.8, 0, 0, 0]]), np.array([[-0.8, 0, 0, 0]])
        assert _hits(base, cells, hit) > 0 and _hits(base, cells, clear) == 0
        assert _hits(base, unplaced, hit) == 0
        at_hit = c.request("check", {"joints": {"joint_1": 0.8}})
        assert not at_hit["valid"] and any("camera" in p for p in at_hit["pairs"])
        assert at_hit["clouds"] == {"camera": "free"}
        assert c.request("check", {"joints": {"joint_1": -0.8}})["valid"]

        # a later cloud replaces it (same id, one object)
        rev = c.request("scene")["revision"]
        moved = in_cam + np.float32(0.5)
        pub.put(cloud(moved, CAMERA))
        assert wait_for(lambda: c.request("scene")["revision"] > rev, 60)
        objects = c.request("scene")["objects"]
        assert [o["id"] for o in objects] == ["camera"]
        np.testing.assert_array_equal(decode_points(objects[0]["points"]).points,
                                      moved.astype(np.float64))

        # a frame that is no link: refused in the log, nothing changes, still serving
        rev, scene = c.request("scene")["revision"], c.request("scene")
        pub.put(cloud(in_cam, "camera_depth_optical_frame"))
        assert wait_for(lambda: any("ROS2_UNKNOWN_FRAME" in ln for ln in srv.stderr_lines),
                        30), "\n".join(srv.stderr_lines[-20:])
        line = next(ln for ln in srv.stderr_lines if "ROS2_UNKNOWN_FRAME" in ln)
        assert "camera_depth_optical_frame" in line and CAMERA in line and "ERROR" in line
        time.sleep(0.5)
        assert c.request("scene") == scene and scene["revision"] == rev
        pub.put(cloud(in_cam, CAMERA))  # and the next good cloud is taken
        assert wait_for(lambda: c.request("scene")["revision"] > rev, 60)
    said = [ln for ln in srv.stderr_lines if CLOUDS in ln and "INFO" in ln]
    assert any("points object 'camera'" in ln and "5 Hz" in ln for ln in said), said


# -- the camera topic, and the client's perceive ------------------------------------------
BOX = 0.12
MAP = {"dictionary": "4x4_50", "size": 0.08,
       "objects": {"3": {"id": "box", "shape": "box", "size": [BOX, BOX, BOX],
                         "offset": {"xyz": [-BOX / 2, 0, 0],
                                    "rpy": [math.pi / 2, 0, -math.pi / 2]}}}}


@pytest.fixture(scope="module")
def view(course_ws):
    """The twin's render of the box (tests/service/test_perceive_service.py's scene) by
    the course's camera with ``intr`` (None: its Gazebo sensor's): RGB, and the
    intrinsics."""
    pytest.importorskip("cv2")
    pytest.importorskip("mujoco")
    from arduinobot.description import read_model_text
    from arduinobot.perception.camera import camera_frame
    from arduinobot.perception.intrinsics import camera_sensors
    from arduinobot.perception.markers import MarkerMap
    from arduinobot.perception.twin_view import Light, render

    d = load_description(course_ws.xacro, package_dirs=[course_ws.src])
    (sensor,) = camera_sensors(read_model_text(course_ws.xacro, packages=d.packages)[0])
    cam = camera_frame(d, sensor.link)

    def rgb(pose: np.ndarray, intr: Any = None) -> tuple[np.ndarray, Any]:
        intr = intr or sensor.intrinsics()
        return render(MarkerMap.from_mapping(MAP), {"box": pose}, cam, intr,
                      lights=(Light(direction=(0.2, 0.1, -1.0)),)), intr
    return rgb


def _image(rgb: np.ndarray, encoding: str) -> Any:
    pixels = rgb[:, :, ::-1] if encoding == "bgr8" else rgb
    h, w, _ = pixels.shape
    return T["sensor_msgs/msg/Image"](header=header(CAMERA), height=h, width=w,
                                      encoding=encoding, is_bigendian=0, step=3 * w,
                                      data=np.ascontiguousarray(pixels).reshape(-1))


def _camera_info(intr: Any) -> Any:
    roi = T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                do_rectify=False)
    k = [intr.fx, 0, intr.cx, 0, intr.fy, intr.cy, 0, 0, 1]
    p = [intr.fx, 0, intr.cx, 0, 0, intr.fy, intr.cy, 0, 0, 0, 1, 0]
    return T["sensor_msgs/msg/CameraInfo"](
        header=header(CAMERA), height=intr.height, width=intr.width,
        distortion_model="plumb_bob", d=np.zeros(5), k=np.array(k, float),
        r=np.eye(3).reshape(-1), p=np.array(p, float), binning_x=0, binning_y=0, roi=roi)


def test_perceive_takes_the_camera_topics_latest_image(served, view, tmp_path):
    from arduinobot.description.model import Origin
    from arduinobot.perception.intrinsics import ideal

    srv, session = served
    first = Origin(xyz=(0.7, 0.40, BOX / 2), rpy=(0.0, 0.0, 0.2)).matrix()
    second = Origin(xyz=(0.8, 0.55, BOX / 2), rpy=(0.0, 0.0, -0.3)).matrix()
    # not the Gazebo sensor's 640 x 480: the CameraInfo on camera_info must be the one used
    intr = ideal(800, 600, 1.0)
    images = DesignPublisher(session, DOMAIN, IMAGES, "sensor_msgs/msg/Image")
    infos = DesignPublisher(session, DOMAIN, "/camera/camera_info", "sensor_msgs/msg/CameraInfo")
    assert _subscribed(session, IMAGES) == images.key
    assert _subscribed(session, "/camera/camera_info") == infos.key
    with PlannerClient(srv.endpoint, timeout=120) as c:
        with pytest.raises(cerr.ImageInvalid, match="no image has arrived on /camera/image_raw"):
            c.perceive(topic=True, markers=MAP)
        rgb, _ = view(first, intr)

        def seen() -> Any:
            try:
                return c.perceive(topic=True, markers=MAP)
            except cerr.ImageInvalid:  # the routes are not in place yet: again
                infos.put(_camera_info(intr))
                images.put(_image(rgb, "rgb8"))
                time.sleep(0.5)
                return None
        end = time.monotonic() + 60
        while (dry := seen()) is None and time.monotonic() < end:
            pass
        assert dry is not None
        (det,) = dry.detections
        assert det.object == "box" and det.marker == 3 and dry.revision is None
        assert np.linalg.norm(np.subtract(det.xyz, first[:3, 3])) < 0.005
        assert dry.camera["link"] == CAMERA
        assert dry.image is not None and dry.image["topic"] == IMAGES
        assert dry.image["frame_id"] == CAMERA and dry.image["camera_info"] is True
        assert (dry.image["width"], dry.image["height"]) == (800, 600)
        assert dry.intrinsics["fx"] == pytest.approx(intr.fx)

        # the latest image counts (kept, not queued), in either channel order; applied
        before = c.request("scene")["revision"]
        rgb2, _ = view(second, intr)
        images.put(_image(rgb2, "bgr8"))

        def moved() -> bool:
            got = c.perceive(topic=True, markers=MAP)
            return np.linalg.norm(np.subtract(got.detections[0].xyz, second[:3, 3])) < 0.005
        assert wait_for(moved, 30)
        applied = c.perceive(topic=True, markers=MAP, apply=True)
        assert applied.revision == before + 1
        (box,) = [o for o in c.request("scene")["objects"] if o["id"] == "box"]
        np.testing.assert_allclose(box["xyz"], applied.detections[0].xyz)

        # the command line's `scene see --topic`, as a user types it
        objects = tmp_path / "objects.yaml"
        objects.write_text(yaml.safe_dump({"markers": MAP}))
        out = run_cli("scene", "see", "--topic", "--dry-run", "--markers", str(objects),
                      "--connect", srv.endpoint, timeout=300)
        assert out.returncode == 0, out.stderr
        assert f"image from {IMAGES}: 800 x 600 bgr8, frame {CAMERA}" in out.stdout
        where = re.search(r"marker 3 -> box at \(([-\d.]+), ([-\d.]+), ([-\d.]+)\) m", out.stdout)
        assert where is not None, out.stdout
        assert np.linalg.norm(np.array(where.groups(), float) - second[:3, 3]) < 0.006
        assert "scene at revision" not in out.stdout  # --dry-run

        # an image that is not one: coded, the scene as it was
        scene = c.request("scene")
        images.put(T["sensor_msgs/msg/Image"](header=header(CAMERA), height=600, width=800,
                                              encoding="rgb8", is_bigendian=0, step=2400,
                                              data=np.zeros(2400 * 10, np.uint8)))

        def refused() -> bool:
            try:
                c.perceive(topic=True, markers=MAP)  # the good one, until the bad arrives
            except cerr.ImageInvalid:
                return True
            return False
        assert wait_for(refused, 10)
        with pytest.raises(cerr.ImageInvalid) as e:
            c.perceive(topic=True, markers=MAP, apply=True)
        assert e.value.details["field"] == "image.data" and "truncated" in str(e.value)
        assert c.request("scene") == scene


def test_the_clients_perceive_sends_a_file_or_bytes(served, view, tmp_path):
    from arduinobot.description.model import Origin
    from arduinobot.perception.image import encode

    srv, _ = served
    pose = Origin(xyz=(0.75, 0.45, BOX / 2), rpy=(0.0, 0.0, 0.1)).matrix()
    png = encode(view(pose)[0])
    path = tmp_path / "view.jpg"
    path.write_bytes(encode(view(pose)[0], "jpeg"))
    with PlannerClient(srv.endpoint, timeout=120) as c:
        for image in (png, path, str(path)):
            got = c.perceive(image, markers=MAP, camera=CAMERA)
            (det,) = got.detections
            assert np.linalg.norm(np.subtract(det.xyz, pose[:3, 3])) < 0.005, image
            assert got.image is None and got.revision is None
            assert got.intrinsics["width"] == 640  # the model's Gazebo sensor's
        with pytest.raises(cerr.ImageInvalid):
            c.perceive(b"GIF89a, not a PNG", markers=MAP)
        with pytest.raises(cerr.InvalidRequest) as e:
            c.perceive(png, markers=MAP, camera="wrist_camera")
        assert e.value.details["field"] == "camera"
        with pytest.raises(TypeError):
            c.perceive(markers=MAP)
        with pytest.raises(TypeError):
            c.perceive(png, topic=True, markers=MAP)
