"""Point clouds decoded, bounded and kept as cells (arduinobot.scene.cloud, cloud_filter)."""

from __future__ import annotations

import base64

import numpy as np
import pytest

from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene import cloud
from arduinobot.scene.cloud import (
    Cells,
    check_resolution,
    decode_points,
    encode_points,
    voxelise,
)
from arduinobot.scene.cloud_filter import inside_objects, kept_cells, near_surface
from arduinobot.scene.obstacles import Obstacle


def _spec(raw: bytes, fmt: str = "xyz32") -> dict:
    return {"format": fmt, "data": base64.b64encode(raw).decode()}


@pytest.mark.parametrize("fmt,dtype", [("xyz32", "<f4"), ("xyz64", "<f8")])
def test_decodes_little_endian_points_and_drops_non_finite(fmt, dtype):
    rng = np.random.default_rng(1)
    pts = rng.uniform(-2, 2, (500, 3)).astype(dtype)
    pts[[3, 70]] = np.nan
    pts[100, 1] = np.inf
    # packed by hand, independently of encode_points: x, y, z per point, little endian
    raw = b"".join(np.array(p, dtype=dtype).tobytes() for p in pts)
    out = decode_points(_spec(raw, fmt))
    assert out.dropped == 3 and out.points.shape == (497, 3)
    keep = np.isfinite(pts.astype(float)).all(axis=1)
    np.testing.assert_array_equal(out.points, pts[keep].astype(float))


def test_encode_round_trips():
    pts = np.array([[0.1, -0.2, 0.3], [1.5, 2.5, -3.5]])
    out = decode_points(encode_points(pts, "xyz64"))
    np.testing.assert_array_equal(out.points, pts)


@pytest.mark.parametrize("spec,field", [
    ([1, 2], "cloud"),
    ({"format": "xyz16", "data": "AAAA"}, "cloud.format"),
    ({"format": "xyz32"}, "cloud.data"),
    ({"format": "xyz32", "data": "not base64!"}, "cloud.data"),
    ({"format": "xyz32", "data": base64.b64encode(b"\0" * 13).decode()}, "cloud.data"),
    ({"format": "xyz32", "data": "AAAA", "colour": 1}, "cloud"),
])
def test_hostile_clouds_are_refused_naming_the_field(spec, field):
    with pytest.raises(InvalidRequest) as e:
        decode_points(spec, field="cloud")
    assert e.value.field == field


def test_an_all_nan_cloud_is_refused_with_its_count():
    raw = np.full((40, 3), np.nan, "<f4").tobytes()
    with pytest.raises(InvalidRequest) as e:
        decode_points(_spec(raw), field="add[0].points")
    assert e.value.field == "add[0].points" and e.value.details["dropped"] == 40


def test_the_caps_are_refused_before_the_work(monkeypatch):
    # the real caps on small numbers: the checks are the same arithmetic
    monkeypatch.setattr(cloud, "MAX_CLOUD_POINTS", 10)
    with pytest.raises(InvalidRequest) as e:
        decode_points(encode_points(np.zeros((11, 3))))
    assert e.value.details["limit"] == 10 and e.value.field == "points.data"
    assert len(decode_points(encode_points(np.zeros((10, 3)))).points) == 10
    monkeypatch.setattr(cloud, "MAX_CLOUD_BYTES", 16)  # 2 points are 24 bytes, 32 in base64
    with pytest.raises(InvalidRequest) as e:
        decode_points(encode_points(np.zeros((2, 3))))
    # refused on the text's length, before decoding ("a cloud of 24 bytes" would be after)
    assert e.value.details["limit"] == 16 and e.value.message.endswith("a cloud of more than 16 bytes")


def test_the_real_caps():
    assert cloud.MAX_CLOUD_POINTS == 2_000_000 and cloud.MAX_CLOUD_BYTES == 32 * 2**20
    assert cloud.MAX_CLOUD_BASE64 >= cloud.MAX_CLOUD_BYTES * 4 // 3


@pytest.mark.parametrize("bad", [0.001, 0.2, True, "0.01", float("nan")])
def test_resolution_outside_its_range_is_refused(bad):
    with pytest.raises(InvalidRequest) as e:
        check_resolution(bad, field="add[0].resolution")
    assert e.value.field == "add[0].resolution"


def test_voxelise_keeps_each_occupied_cell_once():
    rng = np.random.default_rng(2)
    pts = rng.uniform(-0.5, 0.5, (20_000, 3))
    cells, inverse = voxelise(pts, 0.05)
    # the same cells by Python sets, point by point
    expect = {tuple(int(v) for v in np.floor(p / 0.05)) for p in pts}
    assert {tuple(r) for r in cells.index.tolist()} == expect
    assert len(cells) == len(expect)
    # every point lies inside the box of its cell
    lo = cells.index[inverse] * 0.05
    assert ((pts >= lo - 1e-12) & (pts <= lo + 0.05 + 1e-12)).all()


def test_a_cloud_too_wide_for_its_grid_is_refused():
    pts = np.array([[0.0, 0.0, 0.0], [3000.0, 0.0, 0.0]])
    with pytest.raises(InvalidRequest) as e:
        voxelise(pts, 0.002, field="add[1].points")
    assert e.value.field == "add[1].points" and "limit" in e.value.details


def test_inside_objects_by_shape():
    cells = Cells(np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]]), 0.01)
    c = cells.centers  # (0.005, ...), (0.105, ...), ...
    box = Obstacle("b", "box", size=(0.02, 0.02, 0.02), xyz=(0.0, 0.0, 0.0))
    ball = Obstacle("s", "sphere", radius=0.01, xyz=tuple(c[1]))
    can = Obstacle("c", "cylinder", radius=0.01, length=0.05, xyz=tuple(c[2]),
                   rpy=(1.5707963, 0.0, 0.0))
    mask = inside_objects(cells, [box, ball, can])
    assert mask.tolist() == [True, True, True, False]
    # the padding grows them: the fourth cell's centre is 0.1 m above the box's top
    far = Obstacle("f", "box", size=(0.02, 0.02, 0.02), xyz=tuple(c[3] + [0.0, 0.0, 0.02]))
    assert not inside_objects(cells, [far], 0.005)[3]
    assert inside_objects(cells, [far], 0.011)[3]


def test_near_surface_takes_cells_that_may_reach_the_padding():
    cells = Cells(np.array([[0, 0, 0], [0, 0, 5], [0, 0, 20]]), 0.01)
    surface = np.array([[0.005, 0.005, -0.01]])  # 1.5 cm below the first centre
    near = near_surface(cells, surface, 0.01)
    assert near.tolist() == [True, False, False]


def test_kept_cells_counts_every_point_once():
    rng = np.random.default_rng(3)
    table = np.column_stack([rng.uniform(-0.5, 0.5, 4000), rng.uniform(-0.5, 0.5, 4000),
                             np.full(4000, 0.001)])
    mug = rng.normal([0.2, 0.2, 0.07], 0.01, (500, 3))
    arm = rng.normal([-0.3, -0.3, 0.2], 0.01, (300, 3))
    pts = np.vstack([table, mug, arm])
    surface = rng.normal([-0.3, -0.3, 0.2], 0.01, (2000, 3))
    mug_obj = Obstacle("mug", "cylinder", radius=0.05, length=0.1, xyz=(0.2, 0.2, 0.07))
    cells, counts = kept_cells(pts, 0.01, dropped=7, surface=surface, objects=[mug_obj])
    assert counts.points == len(pts) + 7 and counts.dropped == 7
    assert counts.kept + counts.robot + counts.objects == len(pts)
    assert (counts.kept, counts.robot, counts.objects) == (4000, 300, 500)
    assert counts.cells == len(cells)
    # what is kept is the table, whole: one layer of cells
    assert set(cells.index[:, 2].tolist()) == {0}
    assert len(cells) == len(voxelise(table, 0.01)[0])
