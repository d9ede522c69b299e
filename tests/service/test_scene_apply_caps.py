"""The scene apply's payload cap holds the biggest cloud a request may carry (issue 40):
a cloud is refused by its own caps, naming its field, never by the apply's size."""

from __future__ import annotations

import base64

import numpy as np
import orjson
import pytest

from arduinobot.contract import caps, wire
from arduinobot.contract.errors import InvalidRequest
from arduinobot.scene.cloud_spec import CloudSpec
from arduinobot.service.scene.apply import MAX_APPLY_PAYLOAD, decode_apply

# the most xyz64 points within the cloud's byte cap: 1,398,101 (24 bytes each)
BIGGEST_XYZ64 = caps.MAX_CLOUD_BYTES // 24


def _apply(n: int, fmt: str = "xyz64") -> bytes:
    # a cloud of n points along a line (finite, several cells), one object of the apply
    dtype = "<f8" if fmt == "xyz64" else "<f4"
    pts = np.zeros((n, 3), dtype)
    pts[:, 0] = np.linspace(0.3, 0.5, n)
    data = base64.b64encode(pts.tobytes()).decode("ascii")
    return orjson.dumps({"add": [{"id": "camera", "shape": "points", "resolution": 0.01,
                                  "points": {"format": fmt, "data": data}}]})


def test_the_apply_cap_is_the_biggest_cloud_in_base64_and_room_for_the_rest():
    biggest = 4 * -(-caps.MAX_CLOUD_BYTES // 3)
    assert MAX_APPLY_PAYLOAD is caps.MAX_APPLY_PAYLOAD
    assert MAX_APPLY_PAYLOAD == biggest + 16 * 2**20
    assert str(MAX_APPLY_PAYLOAD) in wire.schema("scene_apply_request")["description"]


def test_an_apply_of_the_biggest_cloud_passes_the_payload_cap_and_its_cloud_is_kept():
    payload = _apply(BIGGEST_XYZ64)
    # ~44.7 MB: the old 16 MiB cap refused it by its size
    assert 4 * -(-caps.MAX_CLOUD_BYTES // 3) - 32 < len(payload) < MAX_APPLY_PAYLOAD
    change = decode_apply(payload)  # the size cap, the depth, the schema
    spec = CloudSpec.from_mapping(change["add"][0], link_names=("base_link",),
                                  where="add[0]")
    assert len(spec.points.points) == BIGGEST_XYZ64 and spec.points.dropped == 0


def test_one_point_more_is_refused_by_the_clouds_byte_cap_naming_its_field():
    change = decode_apply(_apply(BIGGEST_XYZ64 + 1))  # still under the apply's cap
    with pytest.raises(InvalidRequest) as e:
        CloudSpec.from_mapping(change["add"][0], link_names=("base_link",), where="add[0]")
    assert e.value.field == "add[0].points.data"
    assert e.value.details["limit"] == caps.MAX_CLOUD_BYTES


def test_the_most_xyz32_points_pass_and_one_more_is_refused_by_the_point_cap():
    change = decode_apply(_apply(caps.MAX_CLOUD_POINTS, "xyz32"))
    spec = CloudSpec.from_mapping(change["add"][0], link_names=(), where="add[0]")
    assert len(spec.points.points) == caps.MAX_CLOUD_POINTS
    change = decode_apply(_apply(caps.MAX_CLOUD_POINTS + 1, "xyz32"))
    with pytest.raises(InvalidRequest) as e:
        CloudSpec.from_mapping(change["add"][0], link_names=(), where="add[0]")
    assert e.value.field == "add[0].points.data"
    assert e.value.details["limit"] == caps.MAX_CLOUD_POINTS


def test_a_payload_one_byte_over_the_apply_cap_is_refused_by_its_size():
    with pytest.raises(InvalidRequest) as e:
        decode_apply(b" " * (MAX_APPLY_PAYLOAD + 1))
    assert e.value.details["limit"] == MAX_APPLY_PAYLOAD
