"""Unknown space as occupied: the camera's shadow (arduinobot.scene.cloud_unknown)."""

from __future__ import annotations

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene import cloud_unknown
from arduinobot.scene.cloud_unknown import Camera, shadow_cells, shadow_resolution


def _in(cells, p) -> bool:
    key = tuple(int(v) for v in np.floor(np.asarray(p) / cells.resolution))
    return key in {tuple(r) for r in cells.index.tolist()}


@pytest.fixture(scope="module")
def wall():
    """A camera at 0.3 m height looking along +x at a wall patch 1 m away, 0.4 m wide:
    the points a depth camera returns, 2 mm apart."""
    g = np.arange(-0.2, 0.2, 0.002)
    y, z = np.meshgrid(g, g)
    pts = np.column_stack([np.full(y.size, 1.0), y.ravel(), z.ravel() + 0.3])
    pose = np.eye(4)
    pose[2, 3] = 0.3
    cam = Camera(pose, hfov=0.8, vfov=0.8, range=2.0)
    return shadow_cells(pts, cam, 0.02), cam


def test_behind_the_wall_is_shadow_and_in_front_is_seen(wall):
    cells, _ = wall
    assert _in(cells, (1.5, 0.0, 0.3)) and _in(cells, (1.9, 0.1, 0.35))
    assert not _in(cells, (0.5, 0.0, 0.3)) and not _in(cells, (0.9, 0.1, 0.25))


def test_a_ray_without_a_return_is_unknown_all_along(wall):
    cells, _ = wall
    # u = y / x = 0.35: beyond the wall's 0.2, inside the 0.42 of the field of view
    assert _in(cells, (0.5, 0.175, 0.3)) and _in(cells, (1.5, 0.525, 0.3))


def test_outside_the_frustum_is_not_stated(wall):
    cells, cam = wall
    assert not _in(cells, (2.5, 0.0, 0.3))  # beyond the range
    assert not _in(cells, (1.0, 0.8, 0.3))  # outside the field of view
    assert not _in(cells, (-0.5, 0.0, 0.3))  # behind the camera
    assert cells.resolution == shadow_resolution(cam, 0.02)


def test_a_cell_partly_behind_the_surface_counts(wall):
    cells, _ = wall
    # the wall at x = 1.0 runs through the cells at x in [0.98, 1.0) and [1.0, 1.02)
    r = cells.resolution
    assert _in(cells, (1.0 - r / 2, 0.0, 0.3))


def test_a_big_frustum_gets_a_coarser_grid_and_a_huge_one_is_refused(monkeypatch):
    cam = Camera(np.eye(4), hfov=1.5, vfov=1.2, range=6.0)
    assert shadow_resolution(cam, 0.01) > 0.05
    monkeypatch.setattr(cloud_unknown, "MAX_SHADOW_CANDIDATES", 1000)
    with pytest.raises(InvalidRequest) as e:
        shadow_cells(np.array([[1.0, 0, 0]]), cam, 0.01, where="add[0].camera")
    assert e.value.field == "add[0].camera.range"


@pytest.mark.parametrize("data,field", [
    ({"hfov": 0.8, "vfov": 0.8}, "camera.range"),
    ({"hfov": 4.0, "vfov": 0.8, "range": 2}, "camera.hfov"),
    ({"hfov": 0.8, "vfov": True, "range": 2}, "camera.vfov"),
    ({"hfov": 0.8, "vfov": 0.8, "range": 50}, "camera.range"),
    ([0.8], "camera"),
])
def test_bad_cameras_are_refused(data, field):
    with pytest.raises(InvalidRequest) as e:
        Camera.from_mapping(data, np.eye(4))
    assert e.value.field == field
