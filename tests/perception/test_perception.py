"""Perception's parts (src/arduinobot/perception/): intrinsics from a camera_info YAML,
the marker map's checks, the optical frame, and bad images refused with their codes
before anything is guessed (issue 41)."""

from __future__ import annotations

import math

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")
pytest.importorskip("mujoco")

from arduinobot.contract.codes import Code  # noqa: E402
from arduinobot.contract.errors import InvalidRequest  # noqa: E402
from arduinobot.description import load_description, read_model_text  # noqa: E402
from arduinobot.description.model import Origin  # noqa: E402
from arduinobot.perception.camera import camera_frame, optical_frame_of  # noqa: E402
from arduinobot.perception.errors import (  # noqa: E402
    ImageInvalid,
    MarkerRefused,
    NoMarker,
    UnknownMarker,
)
from arduinobot.perception.image import encode  # noqa: E402
from arduinobot.perception.intrinsics import from_camera_info, ideal  # noqa: E402
from arduinobot.perception.locate import perceive  # noqa: E402
from arduinobot.perception.markers import MarkerMap, load_marker_map  # noqa: E402
from arduinobot.perception.twin_view import Light, render  # noqa: E402
from arduinobot.scene.shapes import Cylinder  # noqa: E402

BOX = 0.12


def _map(*ids: int) -> MarkerMap:
    return MarkerMap.from_mapping({
        "dictionary": "4x4_50", "size": 0.08,
        "objects": {str(i): {"id": f"box{i}", "shape": "box", "size": [BOX, BOX, BOX],
                             "offset": {"xyz": [-BOX / 2, 0, 0],
                                        "rpy": [math.pi / 2, 0, -math.pi / 2]}}
                    for i in ids}})


@pytest.fixture(scope="module")
def course(course_ws):
    d = load_description(course_ws.xacro, package_dirs=[course_ws.src])
    from arduinobot.perception.intrinsics import camera_sensors
    (sensor,) = camera_sensors(read_model_text(course_ws.xacro, packages=d.packages)[0])
    return d, sensor.intrinsics()


def _view(course, markers: MarkerMap, poses: dict[str, np.ndarray]) -> bytes:
    d, intr = course
    rgb = render(markers, poses, camera_frame(d, "rgb_camera_link"), intr,
                 lights=(Light(direction=(0.2, 0.1, -1.0)),))
    return encode(rgb)


def _see(course, image: bytes, markers: MarkerMap, **kw):
    d, intr = course
    return perceive(image, description=d, markers=markers, camera=kw.pop("camera",
                    "rgb_camera_link"), intrinsics=intr, **kw)


AHEAD = Origin(xyz=(0.7, 0.4, BOX / 2), rpy=(0.0, 0.0, 0.2)).matrix()


# --- intrinsics -------------------------------------------------------------------------

def test_a_calibration_files_camera_matrix_and_distortion_are_read() -> None:
    text = """image_width: 2304
image_height: 1296
camera_name: pi_camera_3
camera_matrix: {rows: 3, cols: 3, data: [1810.5, 0, 1150.2, 0, 1812.25, 650.75, 0, 0, 1]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [0.1, -0.2, 0.001, 0.002, 0.05]}
"""
    i = from_camera_info(text)
    assert (i.fx, i.fy, i.cx, i.cy, i.width, i.height) == (1810.5, 1812.25, 1150.2, 650.75,
                                                           2304, 1296)
    assert i.distortion == (0.1, -0.2, 0.001, 0.002, 0.05)
    msg = from_camera_info("width: 640\nheight: 480\nk: [500, 0, 320, 0, 501, 240, 0, 0, 1]\n"
                           "d: [0, 0, 0, 0, 0]\n")
    assert (msg.fx, msg.fy, msg.distortion) == (500.0, 501.0, ())


def test_a_camera_info_without_a_matrix_names_the_field() -> None:
    with pytest.raises(InvalidRequest) as e:
        from_camera_info("image_width: 640\n")
    assert e.value.field == "intrinsics"


def test_the_pi_camera_3_sensor_of_the_issue_gives_its_focal_length() -> None:
    i = ideal(2304, 1296, 1.15)
    assert i.fx == pytest.approx(1152 / math.tan(0.575))
    assert i.fovy() == pytest.approx(2 * math.atan(648 / i.fy))


# --- the marker map ---------------------------------------------------------------------

def test_an_objects_yaml_reads_as_a_marker_map() -> None:
    m = load_marker_map("""markers:
  dictionary: 4x4_50
  size: 0.04
  objects:
    7: {id: can, shape: cylinder, radius: 0.03, length: 0.1,
        offset: {xyz: [0.03, 0, 0], rpy: [1.5707963, 0, 1.5707963]}}
""")
    assert m.size == 0.04 and m.objects[7].id == "can"
    assert m.objects[7].geometry == Cylinder(0.03, 0.1)
    assert m.objects[7].extent() == pytest.approx(math.hypot(0.03, 0.05))


@pytest.mark.parametrize(("patch", "field"), [
    ({"dictionary": "7x7_9"}, "markers.dictionary"),
    ({"size": 0}, "markers.size"),
    ({"objects": {"x": {"id": "a", "shape": "box", "size": [1, 1, 1]}}}, "markers.objects.x"),
    ({"objects": {"1": {"id": "a", "shape": "cone"}}}, "markers.objects.1.shape"),
    # a shape of a file of the server's is no marked object (a marker map comes in requests)
    ({"objects": {"1": {"id": "a", "shape": "mesh"}}}, "markers.objects.1.shape"),
    ({"objects": {"1": {"id": "a", "shape": "box", "mesh_path": "/etc/hostname"}}},
     "markers.objects.1"),
    ({"objects": {"1": {"id": "a", "shape": "box", "size": [1, -1, 1]}}},
     "markers.objects.1.size"),
    ({"objects": {"1": {"id": "a", "shape": "box", "size": [1, 1, 1]},
                  "2": {"id": "a", "shape": "sphere", "radius": 1}}}, "markers.objects"),
])
def test_a_bad_marker_map_names_its_field(patch, field) -> None:
    base = {"dictionary": "4x4_50", "size": 0.05,
            "objects": {"1": {"id": "a", "shape": "box", "size": [1, 1, 1]}}}
    with pytest.raises(InvalidRequest) as e:
        MarkerMap.from_mapping({**base, **patch})
    assert e.value.field == field


# --- the optical frame ------------------------------------------------------------------

def test_a_camera_link_that_does_not_exist_is_refused_before_the_image(course) -> None:
    with pytest.raises(InvalidRequest) as e:
        _see(course, b"not even an image", _map(3), camera="wrist_camera")
    assert e.value.field == "camera" and e.value.code == Code.INVALID_REQUEST
    assert "rgb_camera_link" in e.value.message  # says which camera links there are


def test_an_optical_child_frame_is_used_with_its_z_forward(tmp_path) -> None:
    urdf = tmp_path / "cam.urdf"
    urdf.write_text("""<robot name="cam">
  <link name="base_link"/>
  <link name="cam_link"/>
  <link name="cam_optical_frame"/>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base_link"/><child link="tip"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="c" type="fixed"><parent link="base_link"/><child link="cam_link"/>
    <origin xyz="0.1 0 0.2"/></joint>
  <joint name="o" type="fixed"><parent link="cam_link"/><child link="cam_optical_frame"/>
    <origin rpy="-1.5707963267948966 0 -1.5707963267948966"/></joint>
</robot>""")
    d = load_description(urdf)
    assert optical_frame_of(d, "cam_link") == ("cam_optical_frame", True)
    # the ROS optical frame is the same frame this module builds from a +x camera link
    via_child = camera_frame(d, "cam_link").pose
    np.testing.assert_allclose(via_child[:3, 2], [1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(via_child[:3, 0], [0, -1, 0], atol=1e-9)
    np.testing.assert_allclose(via_child[:3, 3], [0.1, 0, 0.2], atol=1e-12)
    with pytest.raises(InvalidRequest) as e:
        camera_frame(d, "cam_link", {"j9": 0.0})
    assert e.value.field == "state.j9"


# --- bad images: coded errors -----------------------------------------------------------

def test_bytes_that_are_not_an_image_are_image_invalid(course) -> None:
    with pytest.raises(ImageInvalid) as e:
        _see(course, b"GIF89a not a png", _map(3))
    assert e.value.code == Code.IMAGE_INVALID and e.value.details["field"] == "image"
    png = _view(course, _map(3), {"box3": AHEAD})
    with pytest.raises(ImageInvalid):
        _see(course, png[: len(png) // 3], _map(3))  # truncated
    with pytest.raises(ImageInvalid) as e:
        _see(course, png, _map(3), image_format="jpeg")
    assert e.value.details["field"] == "image.format"


def test_an_all_black_image_is_image_invalid(course) -> None:
    with pytest.raises(ImageInvalid) as e:
        _see(course, encode(np.zeros((480, 640, 3), np.uint8)), _map(3))
    assert "one colour" in e.value.message


def test_a_view_with_no_marker_is_no_marker(course) -> None:
    with pytest.raises(NoMarker) as e:
        _see(course, _view(course, _map(3), {}), _map(3))  # the floor only
    assert e.value.code == Code.NO_MARKER and e.value.details["dictionary"] == "4x4_50"


def test_a_marker_not_in_the_map_is_unknown_marker(course) -> None:
    image = _view(course, _map(7), {"box7": AHEAD})
    with pytest.raises(UnknownMarker) as e:
        _see(course, image, _map(3))
    assert e.value.code == Code.UNKNOWN_MARKER
    assert e.value.details["markers"] == [7] and e.value.details["known"] == [3]


def test_a_marker_too_small_or_too_oblique_is_refused(course) -> None:
    image = _view(course, _map(3), {"box3": AHEAD})
    seen = _see(course, image, _map(3))  # the same image is fine with the defaults
    (det,) = seen.detections
    with pytest.raises(MarkerRefused) as e:
        _see(course, image, _map(3), min_side_px=det.view.side_px + 1)
    assert e.value.reason == "too_small" and e.value.code == Code.MARKER_REFUSED
    with pytest.raises(MarkerRefused) as e:
        _see(course, image, _map(3), max_angle=det.view.angle - 0.01)
    assert e.value.reason == "grazing"


def test_a_jpeg_gives_the_pose_and_the_padding_grows_the_box(course) -> None:
    d, intr = course
    rgb = render(_map(3), {"box3": AHEAD}, camera_frame(d, "rgb_camera_link"), intr,
                 lights=(Light(direction=(0.2, 0.1, -1.0)),))
    (det,) = _see(course, encode(rgb, "jpeg", quality=90), _map(3)).detections
    assert np.linalg.norm(det.pose[:3, 3] - AHEAD[:3, 3]) < 0.005
    assert 0.0005 < det.uncertainty < 0.02
    padded, bare = det.obstacle(), det.obstacle(padded=False)
    assert bare.size == (BOX, BOX, BOX)
    assert padded.size == pytest.approx([BOX + 2 * det.uncertainty] * 3)
    assert padded.id == "box3" and padded.xyz == bare.xyz
    wire = det.to_dict()
    assert wire["object"] == "box3" and wire["marker"] == 3
    np.testing.assert_allclose(wire["marker_xyz"], det.marker_pose[:3, 3])


# --- layering ---------------------------------------------------------------------------

def test_only_the_service_and_the_command_line_import_perception() -> None:
    """The core never imports perception (OpenCV is the optional see extra), perception
    imports nothing above it, and OpenCV and MuJoCo only inside its functions."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "src" / "arduinobot"

    def imports(path: Path, *, top: bool = False) -> set[str]:
        tree = ast.parse(path.read_text("utf-8"))
        nodes = tree.body if top else list(ast.walk(tree))
        out: set[str] = set()
        for n in nodes:
            if isinstance(n, ast.Import):
                out |= {a.name for a in n.names}
            elif isinstance(n, ast.ImportFrom) and n.module and n.level == 0:
                out.add(n.module)
        return out

    core = ("planner", "execution", "description", "contract", "scene", "ros2", "client",
            "viewer")
    bad = {str(p): m for pkg in core for p in (root / pkg).rglob("*.py")
           if (m := {i for i in imports(p) if i.startswith("arduinobot.perception")})}
    assert not bad
    users = {p.relative_to(root).parts[0] for p in root.rglob("*.py")
             if any(i.startswith("arduinobot.perception") for i in imports(p))}
    assert users == {"perception", "service", "cli"}
    files = list((root / "perception").glob("*.py"))
    assert len(files) >= 8
    for p in files:
        assert not {i for i in imports(p) if i.split(".")[1:2] in (["service"], ["cli"],
                                                                  ["client"], ["viewer"])}, p
        assert not imports(p, top=True) & {"cv2", "mujoco"}, p


def test_an_image_over_the_pixel_cap_is_refused_from_its_header(course) -> None:
    from arduinobot.perception.image import MAX_PIXELS, header_size
    small = encode(np.full((48, 64, 3), 128, np.uint8))
    assert header_size(small, "png") == (64, 48)
    assert header_size(encode(np.full((48, 64, 3), 128, np.uint8), "jpeg"), "jpeg") == (64, 48)
    # a 5000 x 5000 header (a decompression bomb's) is refused before decoding
    big = small[:16] + (5000).to_bytes(4, "big") * 2 + small[24:]
    assert 5000 * 5000 > MAX_PIXELS
    with pytest.raises(ImageInvalid) as e:
        _see(course, big, _map(3))
    assert "cap" in e.value.message
