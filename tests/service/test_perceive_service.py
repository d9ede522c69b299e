"""`<prefix>/perceive` through a real `arduinobot serve` on the course's workspace (its
base camera): the twin's rendered view gives the box in the kept scene, seen again it
moves, and bad images are coded errors that leave the scene as it was (issue 41)."""

from __future__ import annotations

import base64
import math
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

pytest.importorskip("cv2")
pytest.importorskip("mujoco")

from arduinobot.client import errors as cerr  # noqa: E402
from arduinobot.client.client import PlannerClient  # noqa: E402
from arduinobot.description import load_description, read_model_text  # noqa: E402
from arduinobot.description.model import Origin  # noqa: E402
from arduinobot.perception.camera import camera_frame  # noqa: E402
from arduinobot.perception.image import encode  # noqa: E402
from arduinobot.perception.intrinsics import camera_sensors  # noqa: E402
from arduinobot.perception.markers import MarkerMap  # noqa: E402
from arduinobot.perception.twin_view import Light, render  # noqa: E402
from tests.helpers.serve import REPO, start_server  # noqa: E402

pytestmark = pytest.mark.slow

BOX = 0.12
MAP = {"dictionary": "4x4_50", "size": 0.08,
       "objects": {"3": {"id": "box", "shape": "box", "size": [BOX, BOX, BOX],
                         "offset": {"xyz": [-BOX / 2, 0, 0],
                                    "rpy": [math.pi / 2, 0, -math.pi / 2]}}}}
FIRST = Origin(xyz=(0.7, 0.40, BOX / 2), rpy=(0.0, 0.0, 0.2)).matrix()
SECOND = Origin(xyz=(0.8, 0.55, BOX / 2), rpy=(0.0, 0.0, -0.3)).matrix()


@pytest.fixture(scope="module")
def course_service(course_ws, tmp_path_factory):
    srv = start_server(["--workers", "1", str(course_ws.xacro), "--package-dir",
                        str(course_ws.src), "--moveit-config", str(course_ws.moveit_pkg),
                        "--scene-file", str(tmp_path_factory.mktemp("see") / "scene.json")],
                       timeout=240)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def view(course_ws):
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src])
    (sensor,) = camera_sensors(read_model_text(course_ws.xacro, packages=d.packages)[0])
    cam, intr = camera_frame(d, sensor.link), sensor.intrinsics()

    def png(poses: dict[str, np.ndarray], markers: dict[str, Any] = MAP) -> bytes:
        return encode(render(MarkerMap.from_mapping(markers), poses, cam, intr,
                             lights=(Light(direction=(0.2, 0.1, -1.0)),)))
    return png


def _body(image: bytes, **kw: Any) -> dict[str, Any]:
    return {"image": {"format": "png", "data": base64.b64encode(image).decode()},
            "markers": MAP, **kw}


def test_seen_boxes_go_into_the_kept_scene_and_move_when_seen_again(course_service, view):
    with PlannerClient(course_service.endpoint, timeout=60) as c:
        before = c.request("scene")["revision"]
        reply = c.request("perceive", _body(view({"box": FIRST}), apply=True))
        (det,) = reply["detections"]
        assert det["object"] == "box" and det["marker"] == 3
        assert np.linalg.norm(np.subtract(det["xyz"], FIRST[:3, 3])) < 0.005
        assert reply["camera"]["link"] == "rgb_camera_link"  # the model's sensor's
        assert reply["intrinsics"]["width"] == 640
        assert reply["revision"] == before + 1
        scene = c.request("scene")
        (obj,) = scene["objects"]
        assert obj["id"] == "box"
        np.testing.assert_allclose(obj["xyz"], det["xyz"])
        np.testing.assert_allclose(obj["size"], [BOX + 2 * det["uncertainty"]] * 3)

        again = c.request("perceive", _body(view({"box": SECOND}), apply=True))
        assert again["revision"] == before + 2
        (obj,) = c.request("scene")["objects"]  # moved, not doubled
        assert np.linalg.norm(np.subtract(obj["xyz"], SECOND[:3, 3])) < 0.005

        dry = c.request("perceive", _body(view({"box": FIRST})))  # no apply
        assert "revision" not in dry and c.request("scene")["revision"] == before + 2


@pytest.mark.parametrize(("case", "error"), [
    ("not_an_image", cerr.ImageInvalid),
    ("all_black", cerr.ImageInvalid),
    ("no_marker", cerr.NoMarker),
    ("unknown_id", cerr.UnknownMarker),
    ("no_such_camera", cerr.InvalidRequest),
])
def test_bad_images_are_coded_errors_and_change_nothing(course_service, view, case, error):
    images = {
        "not_an_image": lambda: b"GIF89a, not a PNG",
        "all_black": lambda: encode(np.zeros((480, 640, 3), np.uint8)),
        "no_marker": lambda: view({}),
        "unknown_id": lambda: view({"box9": FIRST}, {**MAP, "objects": {
            "9": {**MAP["objects"]["3"], "id": "box9"}}}),
        "no_such_camera": lambda: view({"box": FIRST}),
    }
    extra = {"camera": "wrist_camera"} if case == "no_such_camera" else {}
    with PlannerClient(course_service.endpoint, timeout=60) as c:
        c.request("perceive", _body(view({"box": FIRST}), apply=True))
        before = c.request("scene")
        with pytest.raises(error) as e:
            c.request("perceive", _body(images[case](), apply=True, **extra))
        if case == "no_such_camera":
            assert e.value.details["field"] == "camera"
        assert c.request("scene") == before


def test_scene_see_as_a_user_types_it(course_service, view, tmp_path):
    image = tmp_path / "view.png"
    image.write_bytes(view({"box": SECOND}))
    objects = tmp_path / "objects.yaml"
    objects.write_text("""markers:
  dictionary: 4x4_50
  size: 0.08
  objects:
    3: {id: box, shape: box, size: [0.12, 0.12, 0.12],
        offset: {xyz: [-0.06, 0, 0], rpy: [1.5707963267948966, 0, -1.5707963267948966]}}
""")
    info = tmp_path / "camera_info.yaml"
    info.write_text("image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, "
                    f"data: [{320 / math.tan(1.089 / 2)!r}, 0, 319.5, 0, "
                    f"{320 / math.tan(1.089 / 2)!r}, 239.5, 0, 0, 1]}}\n")
    out = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "scene", "see",
                          str(image), "--camera", "rgb_camera_link", "--intrinsics", str(info),
                          "--markers", str(objects), "--connect", course_service.endpoint],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "marker 3 -> box" in out.stdout and "scene at revision" in out.stdout
    with PlannerClient(course_service.endpoint, timeout=60) as c:
        (obj,) = c.request("scene")["objects"]
    assert np.linalg.norm(np.subtract(obj["xyz"], SECOND[:3, 3])) < 0.005
    bad = subprocess.run([sys.executable, "-m", "arduinobot.cli.main", "scene", "see",
                          str(objects), "--connect", course_service.endpoint],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    assert bad.returncode != 0 and ".png" in bad.stderr


def test_remove_unseen_takes_out_the_maps_objects_not_in_the_image(course_service, view):
    two = {**MAP, "objects": {**MAP["objects"], "5": {
        "id": "crate", "shape": "box", "size": [BOX, BOX, BOX],
        "offset": {"xyz": [-BOX / 2, 0, 0], "rpy": [math.pi / 2, 0, -math.pi / 2]}}}}
    crate = Origin(xyz=(0.75, 0.22, BOX / 2), rpy=(0.0, 0.0, 0.1)).matrix()
    with PlannerClient(course_service.endpoint, timeout=60) as c:
        both = c.request("perceive", {**_body(view({"box": FIRST, "crate": crate}, two)),
                                      "markers": two, "apply": True})
        assert sorted(d["object"] for d in both["detections"]) == ["box", "crate"]
        ids = {o["id"] for o in c.request("scene")["objects"]}
        assert {"box", "crate"} <= ids
        kept = c.request("perceive", {**_body(view({"box": SECOND}, two)), "markers": two,
                                      "apply": True})  # without remove_unseen: stays
        assert kept["removed"] == [] and "crate" in {o["id"] for o in c.request("scene")["objects"]}
        gone = c.request("perceive", {**_body(view({"box": SECOND}, two)), "markers": two,
                                      "apply": True, "remove_unseen": True})
        assert gone["removed"] == ["crate"]
        assert "crate" not in {o["id"] for o in c.request("scene")["objects"]}
