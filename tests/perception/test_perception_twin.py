"""The twin's camera sees what is there: MuJoCo renders the course's base camera
(640 x 480 px, 1.089 rad, its Gazebo sensor) looking at a box with an ArUco marker on it,
and perception puts the box back where it was (issue 41: three box poses, two lights,
within 5 mm and 3 degrees)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("cv2")
pytest.importorskip("mujoco")

from arduinobot.description import load_description, read_model_text  # noqa: E402
from arduinobot.description.model import Origin  # noqa: E402
from arduinobot.perception.camera import camera_frame  # noqa: E402
from arduinobot.perception.image import encode  # noqa: E402
from arduinobot.perception.intrinsics import camera_sensors  # noqa: E402
from arduinobot.perception.locate import perceive  # noqa: E402
from arduinobot.perception.markers import MarkerMap  # noqa: E402
from arduinobot.perception.twin_view import Light, render  # noqa: E402

BOX = 0.12  # [m] a cube, its marker centred on its -x face (towards the camera)
MARKERS = MarkerMap.from_mapping({
    "dictionary": "4x4_50", "size": 0.08,
    "objects": {"3": {"id": "box", "shape": "box", "size": [BOX, BOX, BOX],
                      "offset": {"xyz": [-BOX / 2, 0, 0], "rpy": [math.pi / 2, 0, -math.pi / 2]}}}})

# on the floor in front of the camera (at y = 0.4, 3.5 cm up, looking along +x)
POSES = {
    "ahead": Origin(xyz=(0.70, 0.40, BOX / 2), rpy=(0.0, 0.0, 0.0)),
    "left_turned": Origin(xyz=(0.85, 0.62, BOX / 2), rpy=(0.0, 0.0, 0.45)),
    "right_near": Origin(xyz=(0.55, 0.25, BOX / 2), rpy=(0.0, 0.0, -0.35)),
}
LIGHTS = {
    "overhead": (Light(direction=(0.2, 0.1, -1.0), diffuse=0.8, ambient=0.25),),
    "dim_side": (Light(directional=False, position=(0.2, -0.8, 1.2), direction=(0.5, 1.0, -1.0),
                       diffuse=0.45, ambient=0.1),),
}


@pytest.fixture(scope="module")
def course(course_ws):
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src])
    text, _ = read_model_text(course_ws.xacro, packages=d.packages)
    (sensor,) = camera_sensors(text)
    return d, sensor


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = (np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


@pytest.mark.parametrize("light", sorted(LIGHTS))
@pytest.mark.parametrize("where", sorted(POSES))
def test_a_rendered_box_is_found_within_5_mm_and_3_degrees(course, where, light) -> None:
    d, sensor = course
    intr = sensor.intrinsics()
    cam = camera_frame(d, sensor.link)
    truth = POSES[where].matrix()
    rgb = render(MARKERS, {"box": truth}, cam, intr, lights=LIGHTS[light])
    assert rgb.shape == (480, 640, 3)
    seen = perceive(encode(rgb), description=d, markers=MARKERS, camera=sensor.link,
                    intrinsics=intr)
    (det,) = seen.detections
    assert det.marked.id == "box" and det.marker == 3
    err = float(np.linalg.norm(det.pose[:3, 3] - truth[:3, 3]))
    assert err < 0.005, f"{where}/{light}: {1e3 * err:.1f} mm"
    assert _angle(det.pose, truth) < 3.0
    assert det.view.reprojection_error < 0.5
    # the padding covers the error actually made
    assert det.uncertainty >= err


def test_the_course_cameras_intrinsics_come_from_its_gazebo_sensor(course) -> None:
    _, sensor = course
    assert (sensor.link, sensor.width, sensor.height) == ("rgb_camera_link", 640, 480)
    intr = sensor.intrinsics()
    assert intr.fx == pytest.approx(320 / math.tan(1.089 / 2))
    assert (intr.cx, intr.cy) == (319.5, 239.5)


def test_the_base_camera_looks_along_its_links_x(course) -> None:
    d, sensor = course
    cam = camera_frame(d, sensor.link)
    assert cam.optical is False and cam.frame == "rgb_camera_link"
    np.testing.assert_allclose(cam.pose[:3, 2], [1, 0, 0], atol=1e-12)  # optical z = +x
    np.testing.assert_allclose(cam.pose[:3, 1], [0, 0, -1], atol=1e-12)  # image down = -z
    np.testing.assert_allclose(cam.pose[:3, 3], [0, 0.40, 0.035], atol=1e-12)
