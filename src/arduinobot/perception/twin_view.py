"""The twin's camera: MuJoCo renders what a camera of the model sees (offscreen,
headless), the objects' markers printed on them as textures, so perception runs and is
checked with no hardware.

Headless rendering needs an OpenGL context without a display: Mesa's EGL (llvmpipe on a
machine without a GPU; Debian: libegl1, libegl-mesa0, libgbm1, libgl1-mesa-dri, which
``./dev`` installs), or OSMesa with ``MUJOCO_GL=osmesa``.

The scene is the floor, the lights, the marked objects and any other obstacles given (the
robot's own links are not drawn: a base camera looking out does not see them). MuJoCo's camera looks along its -z
with y up; the optical frame looks along +z with y down: the same x, the other two flipped.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from arduinobot.perception.camera import CameraFrame
from arduinobot.perception.intrinsics import Intrinsics
from arduinobot.perception.markers import MarkerMap, cv_dictionary_name
from arduinobot.scene.obstacles import Obstacle
from arduinobot.scene.shapes import Shape

log = logging.getLogger(__name__)

#: white printed around a marker, as a fraction of its side on each edge: the detector
#: needs a light quiet zone to find the black border (a 6.5 cm marker's label fits an
#: 8 cm face)
QUIET_ZONE = 0.1
MARKER_PX = 480  # [px] the marker's side in its texture: whole pixels per cell (6, 7, 8, 10)
PLATE = 0.0005  # [m] thickness of the printed label (its back inside the object)
PROUD = 0.0001  # [m] the print stands off the face: no depth fight, 0.1 mm off the map


@dataclass(frozen=True)
class Light:
    """A light of the rendered scene: a directional light from ``direction`` (world
    frame, pointing where the light goes) or a spot at ``position`` [m], and its
    ``diffuse`` and ``ambient`` intensity (0..1)."""

    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    position: tuple[float, float, float] = (0.0, 0.0, 3.0)
    directional: bool = True
    diffuse: float = 0.7
    ambient: float = 0.2


def _f(v: Sequence[float] | np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(v))


def marker_texture(dictionary: str, marker: int) -> bytes:
    """The printed label of ``marker``: the marker inside its white quiet zone, as PNG."""
    import cv2

    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, cv_dictionary_name(dictionary)))
    img = cv2.aruco.generateImageMarker(d, marker, MARKER_PX, borderBits=1)
    pad = int(round(QUIET_ZONE * MARKER_PX))  # exactly: the label's side is (1 + 2 q) size
    img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
    if not ok:
        raise RuntimeError(f"could not encode marker {marker}'s texture")
    return bytes(buf.tobytes())


def _label_mesh(name: str, side: float) -> str:
    """A thin square plate of ``side`` [m] in the marker's frame (z out of the print),
    its +z face textured with the whole image upright."""
    h, t = side / 2.0, PLATE
    # front face: texture u to the right (+x), v down (-y): the image's first row at +y
    v = [(-h, h, 0), (h, h, 0), (h, -h, 0), (-h, -h, 0),
         (-h, h, -t), (h, h, -t), (h, -h, -t), (-h, -h, -t)]
    uv = [(0, 0), (1, 0), (1, 1), (0, 1)] * 2
    faces = [(0, 3, 2), (0, 2, 1), (4, 5, 6), (4, 6, 7),
             (0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5),
             (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)]
    return (f'<mesh name="{name}" vertex="{_f(np.array(v))}" '
            f'texcoord="{_f(np.array(uv))}" face="{" ".join(str(i) for f in faces for i in f)}"/>')


def _geom_of(shape: Shape) -> str | None:
    """The MuJoCo geom's type and size of ``shape``; None: it has no MuJoCo primitive (a
    mesh file)."""
    geom = shape.mjcf()
    return None if geom is None else f'type="{geom[0]}" size="{geom[1]}"'


def _frame(pose: np.ndarray) -> str:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(pose[:3, :3]).ravel())
    return f'pos="{_f(pose[:3, 3])}" quat="{_f(q)}"'


def scene_xml(markers: MarkerMap, poses: Mapping[str, np.ndarray], camera: CameraFrame,
              intrinsics: Intrinsics, lights: Sequence[Light],
              obstacles: Sequence[Obstacle] = ()) -> tuple[str, dict[str, bytes]]:
    """The MJCF text of the scene and its texture files (name -> PNG bytes)."""
    assets: dict[str, bytes] = {}
    asset_xml, world = [], []
    for mid, o in sorted(markers.objects.items()):
        if o.id not in poses:
            continue
        pose = np.asarray(poses[o.id], dtype=np.float64)
        png = f"marker{mid}.png"
        assets[png] = marker_texture(markers.dictionary, mid)
        asset_xml += [f'<texture name="t{mid}" type="2d" file="{png}"/>',
                      f'<material name="m{mid}" texture="t{mid}" rgba="1 1 1 1" '
                      'specular="0" shininess="0" reflectance="0"/>',
                      _label_mesh(f"label{mid}", markers.size * (1 + 2 * QUIET_ZONE))]
        label = pose @ o.offset.matrix()
        label[:3, 3] += label[:3, 2] * PROUD
        world += [f'<geom name="{o.id}" {_geom_of(o.geometry)} {_frame(pose)} '
                  'rgba="0.55 0.35 0.2 1"/>',
                  f'<geom name="label{mid}" type="mesh" mesh="label{mid}" material="m{mid}" '
                  f'{_frame(label)}/>']
    for i, ob in enumerate(obstacles):  # what else is there: it can hide a marker
        geom = _geom_of(ob.geometry)
        if geom is None:
            log.warning("twin camera: %s obstacle %s is not drawn", ob.shape, ob.id)
            continue
        world.append(f'<geom name="obstacle{i}" {geom} {_frame(ob.pose())} '
                     'rgba="0.7 0.7 0.65 1"/>')
    for i, li in enumerate(lights):
        where = (f'dir="{_f(li.direction)}" directional="true"' if li.directional
                 else f'pos="{_f(li.position)}" dir="{_f(li.direction)}"')
        world.append(f'<light name="light{i}" {where} diffuse="{_f([li.diffuse] * 3)}" '
                     f'ambient="{_f([li.ambient] * 3)}" specular="0 0 0" castshadow="false"/>')
    # MuJoCo's camera: x as the optical frame's, y and z flipped (it looks along -z)
    rot = camera.pose[:3, :3]
    world.append(f'<camera name="camera" pos="{_f(camera.pose[:3, 3])}" '
                 f'xyaxes="{_f(rot[:, 0])} {_f(-rot[:, 1])}" fovy="{float(np.degrees(intrinsics.fovy()))!r}"/>')
    w, h = max(intrinsics.width, 64), max(intrinsics.height, 64)
    xml = f"""<mujoco model="camera_view">
  <visual><global offwidth="{w}" offheight="{h}"/><quality offsamples="8"/>
    <headlight ambient="0 0 0" diffuse="0 0 0" specular="0 0 0"/></visual>
  <asset>
    <texture name="floor" type="2d" builtin="checker" rgb1="0.45 0.45 0.45" rgb2="0.5 0.5 0.5"
      width="64" height="64"/>
    <material name="floor" texture="floor" texrepeat="20 20" specular="0" reflectance="0"/>
    {chr(10).join(asset_xml)}
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="10 10 0.1" material="floor"/>
    {chr(10).join(world)}
  </worldbody>
</mujoco>"""
    return xml, assets


def render(markers: MarkerMap, poses: Mapping[str, np.ndarray], camera: CameraFrame,
           intrinsics: Intrinsics, *, lights: Sequence[Light] = (Light(),),
           obstacles: Sequence[Obstacle] = ()) -> np.ndarray:
    """The camera's view of the objects at ``poses`` (object id -> world pose, shape
    (4, 4)) among ``obstacles`` (drawn plain: a table can hide a marker): an RGB image,
    shape (height, width, 3) uint8. ``intrinsics`` must be an ideal pinhole (square
    pixels, centred, no distortion), as a Gazebo sensor's are."""
    if intrinsics.width <= 0 or intrinsics.height <= 0:
        raise ValueError("rendering needs the intrinsics' image size")
    if abs(intrinsics.fx - intrinsics.fy) > 1e-6 * intrinsics.fx or intrinsics.distortion:
        raise ValueError("MuJoCo renders an ideal pinhole only: fx = fy, no distortion")
    import mujoco

    xml, assets = scene_xml(markers, poses, camera, intrinsics, lights, obstacles)
    model = mujoco.MjModel.from_xml_string(xml, assets)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    w, h = intrinsics.width, intrinsics.height
    ctx = _gl_context(w, h)
    ctx.make_current()
    try:
        scene = mujoco.MjvScene(model, maxgeom=1000)
        mjr = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, mjr)
        cam = mujoco.MjvCamera()
        cam.type, cam.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, 0
        mujoco.mjv_updateScene(model, data, mujoco.MjvOption(), None, cam,
                               mujoco.mjtCatBit.mjCAT_ALL, scene)
        rect = mujoco.MjrRect(0, 0, w, h)
        mujoco.mjr_render(rect, scene, mjr)
        rgb = np.zeros((h, w, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(rgb, None, rect, mjr)
        mjr.free()
    finally:
        ctx.free()
    return np.flipud(rgb).copy()  # OpenGL's first row is the image's bottom


def _gl_context(width: int, height: int) -> Any:
    """A headless OpenGL context: OSMesa if ``MUJOCO_GL=osmesa`` asks for it, else EGL.
    Made here rather than by ``mujoco.Renderer``, whose backend is fixed when mujoco is
    first imported (a process that imported it with no display has none)."""
    if os.environ.get("MUJOCO_GL", "").lower() == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.egl import GLContext
    return GLContext(width, height)
